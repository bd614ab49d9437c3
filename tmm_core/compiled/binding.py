"""The compiled layer, compiled and bound in one place (numba, cached on disk).

Numba resolves a kernel's global names when it compiles it, so every helper must be compiled and
put where its callers look it up (their module's namespace) before they are. The kernel modules
hold plain functions in numba's subset and compile nothing themselves; this module compiles
them in dependency order, binds each compiled helper into the modules that call it, and keeps
the one registry of compiled entry points. Each stage is compiled on its first use only (the
command line and the numpy path never import numba): the static solve (factorization and load
solve of a batch of configurations), the stored factorizations, the step's shared parts (the
integrator and the history loads), the march, the periodic solver's linearized revolutions and the
reduced model's revolution.

The on-disk cache is :mod:`tmm_core.compiled.cache`'s, keyed by every kernel file: an edit of any
of them compiles afresh by itself.

Owns: compiling and binding the kernels, the registry of compiled entry points and their numba
options. Boundaries: no arithmetic (the kernel modules), no cache policy (kernel_cache).
"""
from __future__ import annotations

import contextlib
import threading
import warnings
from typing import NamedTuple

import numpy as np

from . import ahead, dense, integrators, periodic, reduced_periodic, riccati, step_data, structure, time_step
from . import march as march_kernel     # beside the stage function march() below
from .cache import numba_module

#: The dense helpers every factorization and solve calls (tmm_core.compiled.dense).
DENSE = ("stumpff", "inv3", "mm3", "ldl_inertia", "segment_blocks", "full6", "copy_states", "state_change",
         "iteration_converged", "iteration_start")
#: The compiled layer's one LU (tmm_core.compiled.dense): the joint systems' and the reduced model's.
LU = ("dot", "subtract_rows", "lu_factor", "lu_solve", "lu_solve_many")
#: The load solve on many load sets and its helpers (tmm_core.compiled.step_data; its scratch,
#: maps_scratch, is allocated in Python: tmm_core.compiled.structure.range_workspace).
MAPS = ("sweep_member", "copy_sweep", "solve_loads_many")
#: The march's own helpers (tmm_core.compiled.march).
MARCH = ("shape_products", "corotational_loads", "affine", "anderson_coefficients")
#: The step's parts the march and the linearized revolutions share: the integrator's history and
#: update (tmm_core.compiled.integrators), the history loads, the co-rotational segment, its
#: derivatives and its chord lag (tmm_core.compiled.time_step).
STEP = {integrators: ("history", "advance"),
        time_step: ("history_loads", "corotational_segment", "corotational_tangent", "chord_lag")}
#: The linearized revolution's helpers (tmm_core.compiled.periodic).
LINEARIZED = ("jacobian_row", "close_row", "solved_response", "corotational_blocks", "corotational_response")
#: The reduced revolution's helpers (tmm_core.compiled.reduced_periodic).
REDUCED = ("node_state", "second_order", "corotational_forces", "corotational_term", "segment_state",
           "corotational_gauges", "stage_states", "newton_matrix")

_ENTRY: dict = {}        # the one registry: a stage's (or a single kernel's) compiled entry points


def _bind(jit, module, names, into=()) -> None:
    """Compile ``module.<name>`` for each name and put it in ``module`` and in every module of
    ``into`` that refers to it by that name (a ``from ... import`` or an alias)."""
    for name in names:
        compiled = jit(getattr(module, name))
        for target in (module, *into):
            if target is module or hasattr(target, name):
                setattr(target, name, compiled)


def lu() -> None:
    """Compile the one LU (:data:`LU`) and bind it where it is called: the joint systems'
    factorization and solves and the reduced model's Newton iteration. error_model "numpy": a
    zero pivot gives inf/nan (the reduced step then fails to converge; the factorization reports
    it) instead of raising ZeroDivisionError in a kernel."""
    if "lu" not in _ENTRY:
        jit = numba_module().njit(cache=True, error_model="numpy")
        _bind(jit, dense, LU, into=(riccati, structure, step_data, reduced_periodic))
        _ENTRY["lu"] = True


def static_solve():
    """``(solve_range, iteration_start)``: :func:`tmm_core.compiled.structure.solve_range` as a
    :class:`RangeSolve` (called with the kernel's records but its ``workspace`` and ``kernels``), with the
    factorization, the load solves and the dense helpers bound where they are called, and the
    beam-column iteration's start (:func:`tmm_core.compiled.dense.iteration_start`)."""
    if "static" not in _ENTRY:
        numba = numba_module()
        jit = numba.njit(cache=True, error_model="numpy")
        lu()
        _bind(jit, dense, DENSE, into=(riccati, structure))
        _bind(jit, riccati, ("factor_configuration", "factor_scratch"), into=(time_step,))
        _bind(jit, step_data, MAPS)
        _bind(jit, structure, ("solve_loads",), into=(time_step,))
        _ENTRY["static"] = RangeSolve(numba), dense.iteration_start
    return _ENTRY["static"]


class RangeSolve:
    """:func:`tmm_core.compiled.structure.solve_range`, compiled once per type of its records
    (on disk: numba's cache) with its factorization and load solves passed as first-class
    functions, and called through that compilation's entry point.

    Why not an ordinary call: a kernel calling another kernel has the callee's machine code
    generated again inside its own, so ``solve_range`` took as long to compile as its three
    callees together. Passed as arguments of numba's function type, they are compiled once each,
    and ``solve_range`` compiles in a fraction of the time. The callees' signatures are spelt
    out from the records' types (numba cannot infer a function argument's type), and the entry
    point is called directly: numba's dispatcher would type a function passed to it by its own
    identity and compile the direct call again."""

    def __init__(self, numba):
        self._numba = numba
        #: The kernel's dispatcher (compiled by :meth:`_compile`, or ahead by a helper).
        self.dispatcher = numba.njit(cache=True, error_model="numpy", nogil=True)(structure.solve_range)
        self._kernels = (riccati.factor_configuration, step_data.solve_loads_many, structure.solve_loads)
        self._entries: dict = {}
        self._lock = threading.Lock()

    def __call__(self, b_start, b_stop, segments, configuration, Fn, joints, outputs, checks, iteration, control):
        workspace = structure.range_workspace(segments, configuration, Fn, joints, outputs)
        records = (segments, configuration, Fn, joints, outputs, checks, iteration, control, workspace)
        # numba.typeof of the records takes about 1 ms (a hundred arrays), as long as a small solve:
        # the entry is looked up by their fingerprint, and typed only for a new one.
        fingerprint = _fingerprint(records)
        entry = self._entries.get(fingerprint)
        if entry is None:
            with self._lock, _quiet_function_types(self._numba):
                entry = self._entries.get(fingerprint) or self._compile(
                    tuple(self._numba.typeof(r) for r in records))
                self._entries[fingerprint] = entry
        entry(b_start, b_stop, *records, self._kernels)

    def _compile(self, key):
        """The entry point of ``solve_range`` for the records' types ``key``, its callees compiled
        first for theirs (on a first run, all but the factorization by helper processes, and then
        loaded from the cache)."""
        types = self._numba.types
        segments, configuration, Fn, joints, outputs, checks, _, _, workspace = key
        _, factors, factor_scratch, load_work, maps_scratch = workspace.types
        ends, free, count = joints.types
        counted = types.Tuple((ends, free, types.Array(count.dtype, 1, "C")))
        load_joints = types.Tuple((segments.types[1], segments.types[5], configuration.types[4], ends, free))
        signatures = (
            types.boolean(types.int64, segments, configuration, counted, checks, factors, factor_scratch),
            types.none(types.int64, Fn, load_joints, outputs, factors, maps_scratch),
            types.none(types.int64, Fn, load_joints, outputs, factors, load_work))
        kernels = types.Tuple(tuple(types.FunctionType(s) for s in signatures))
        requests = {"solve_loads_many": signatures[1], "solve_loads": signatures[2],
                    "solve_range": (types.int64, types.int64) + key + (kernels,)}
        # On a first run helpers compile the load solves and this kernel (which needs only its
        # callees' signatures) while this process compiles the factorization: two processes, so
        # that the three run side by side with the march's helper on two cores.
        compiled = dict(zip(("factor_configuration", "solve_loads_many", "solve_loads"), self._kernels),
                        solve_range=self.dispatcher)
        if ahead_pays("solve_loads_many"):
            ahead.start([("solve_loads_many", requests["solve_loads_many"])])
        if ahead_pays("solve_range"):
            ahead.start([(name, requests[name]) for name in ("solve_loads", "solve_range")])
        self._kernels[0].compile(signatures[0])
        for name, signature in requests.items():
            ahead.wait(name)
            entry = compiled[name].compile(signature)     # from the cache if a helper compiled it
        return entry


def _fingerprint(value):
    """What numba's type of ``value`` (arrays, scalars and nested tuples of them) depends on,
    cheaply: an array's dtype, dimensions, layout and writeability, a scalar's Python type."""
    if isinstance(value, tuple):
        return tuple(_fingerprint(v) for v in value)
    if isinstance(value, np.ndarray):
        flags = value.flags
        return value.dtype.num, value.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable
    return type(value)


#: The kernels a helper process can compile ahead (:mod:`tmm_core.compiled.ahead`): name ->
#: (the file stem of its module, the kernel's name there), as the cache names their files.
AHEAD = {"solve_loads_many": ("step_data", "solve_loads_many"), "solve_loads": ("structure", "solve_loads"),
         "solve_range": ("structure", "solve_range"), "march": ("march", "march")}


def dispatcher(name: str):
    """The compiled kernel ``name`` of :data:`AHEAD`, its stage bound (numba's dispatcher)."""
    if name in ("solve_loads_many", "solve_loads", "solve_range"):
        range_solve, _ = static_solve()
        return range_solve.dispatcher if name == "solve_range" else getattr(
            step_data if name == "solve_loads_many" else structure, name)
    if name == "march":
        return march()
    raise KeyError(f"no kernel {name!r} is compiled ahead; known: {sorted(AHEAD)}")


def ahead_pays(name: str) -> bool:
    """Whether compiling kernel ``name`` of :data:`AHEAD` in a helper process saves time now
    (:func:`tmm_core.compiled.ahead.worth_it`: a first run on two cores or more), and this process
    has not compiled or loaded it already (where numba cannot write its cache, the cache would
    stay empty and every march would start a helper)."""
    return not _compiled_here(name) and ahead.worth_it(*AHEAD[name])


def _compiled_here(name: str) -> bool:
    """Whether this process holds a compilation of kernel ``name`` of :data:`AHEAD`."""
    if name == "march":
        return "march" in _ENTRY and bool(_ENTRY["march"].overloads)
    return "static" in _ENTRY and bool(dispatcher(name).overloads)


def compile_ahead(name: str, arguments: tuple) -> None:
    """Have a helper process compile kernel ``name`` of :data:`AHEAD` for the types of
    ``arguments`` (as it will be called), if that pays (:func:`ahead_pays`); the kernel's stage
    waits for it."""
    if ahead_pays(name):
        numba = numba_module()
        ahead.start([(name, tuple(numba.typeof(a) for a in arguments))])


def compile_requests(requests) -> None:
    """Compile each ``(name, signature)`` of ``requests`` into the cache: the helper process of
    :mod:`tmm_core.compiled.ahead` (``python -m tmm_core.compiled``)."""
    with _quiet_function_types(numba_module()):
        for name, signature in requests:
            dispatcher(name).compile(signature)


@contextlib.contextmanager
def _quiet_function_types(numba):
    """Numba's warning, when it compiles a kernel taking a function, that its function type is
    experimental, silenced (the call does not warn): the one use of it, :class:`RangeSolve`, is
    held equal to the numpy path by tests/test_kernels.py."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "First-class function type", numba.NumbaExperimentalFeatureWarning)
        yield


def factored():
    """``(factor_range, factored_solve)`` of :mod:`tmm_core.compiled.time_step`, compiled (the
    stored factorizations of a range of a batch, without the GIL; the solve on one of them,
    inlined where it is called)."""
    if "factored" not in _ENTRY:
        numba = numba_module()
        static_solve()                               # the factorization and the load solve it calls
        _bind(numba.njit(cache=True, error_model="numpy", nogil=True), time_step, ("factor_range",))
        _bind(numba.njit(cache=True, error_model="numpy", inline="always"), time_step, ("factored_solve",),
              into=(march_kernel,))
        _ENTRY["factored"] = time_step.factor_range, time_step.factored_solve
    return _ENTRY["factored"]


def step_parts() -> None:
    """Compile the step's shared parts (:data:`STEP`) and bind them into the march, the
    linearized revolutions and the reduced revolution (plain numba options: the march's fast-math flags stay its own).
    Inlined where they are called: a call passing the model's record of arrays cost the march
    about 3 us a step (a third of it) against their arithmetic inlined."""
    if "step" not in _ENTRY:
        jit = numba_module().njit(cache=True, inline="always")
        for module, names in STEP.items():
            _bind(jit, module, names, into=(march_kernel, periodic, reduced_periodic))
        _ENTRY["step"] = True


class Linearized(NamedTuple):
    """The periodic solver's compiled linearized revolutions (:mod:`tmm_core.compiled.periodic`)."""

    push: object
    velocities: object


def linearized() -> Linearized:
    """:func:`tmm_core.compiled.periodic.push` and ``velocities``, compiled with the step's parts."""
    if "linearized" not in _ENTRY:
        step_parts()
        jit = numba_module().njit(cache=True)
        _bind(jit, periodic, LINEARIZED)
        _ENTRY["linearized"] = Linearized(jit(periodic.push), jit(periodic.velocities))
    return _ENTRY["linearized"]


def march():
    """:func:`tmm_core.compiled.march.march`, compiled with its helpers, the step's shared parts and
    the stored-factorization solve (once a helper compiling it ahead has ended: it is then
    loaded from the cache)."""
    ahead.wait("march")
    if "march" not in _ENTRY:
        numba = numba_module()
        factored()
        step_parts()
        # Reassociation lets LLVM vectorise the map products (dot-product reductions); no other
        # fast-math flag: the march tests for non-finite values.
        jit = numba.njit(cache=True, fastmath={"reassoc", "contract"})
        _bind(jit, march_kernel, MARCH)
        _ENTRY["march"] = jit(march_kernel.march)
    return _ENTRY["march"]


def reduced_revolution():
    """:func:`tmm_core.compiled.reduced_periodic.revolution`, compiled with its helpers."""
    if "reduced" not in _ENTRY:
        numba = numba_module()
        # error_model "numpy": a singular Newton matrix gives inf/nan (the step then fails to
        # converge, as in the numpy path) instead of raising ZeroDivisionError in the kernel.
        jit = numba.njit(cache=True, error_model="numpy")
        lu()
        step_parts()                                 # the co-rotational segment
        _bind(jit, reduced_periodic, REDUCED)
        _ENTRY["reduced"] = jit(reduced_periodic.revolution)
    return _ENTRY["reduced"]

