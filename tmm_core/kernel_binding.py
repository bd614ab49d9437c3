"""The compiled layer, compiled and bound in one place (numba, cached on disk).

Numba resolves a kernel's global names when it compiles it, so every helper must be compiled and
put where its callers look it up (their module's namespace) before they are. The kernel modules
hold plain functions in numba's subset and compile nothing themselves; this module compiles
them in dependency order, binds each compiled helper into the modules that call it, and keeps
the one registry of compiled entry points. Each stage is compiled on its first use only (the
command line and the numpy path never import numba): the static solve (factorization and load
solve of a batch of configurations), the stored factorizations, the march, the reduced model's
revolution, and single kernels without helpers of their own (the periodic solver's).

The on-disk cache is :mod:`tmm_core.kernel_cache`'s, keyed by every kernel file: an edit of any
of them compiles afresh by itself.

Owns: compiling and binding the kernels, the registry of compiled entry points and their numba
options. Boundaries: no arithmetic (the kernel modules), no cache policy (kernel_cache).
"""
from __future__ import annotations

from . import kernels, kernels_dense, kernels_factor, kernels_factored, kernels_maps, kernels_reduced, kernels_static
from .kernel_cache import numba_module

#: The dense helpers every factorization and solve calls (tmm_core.kernels_dense).
DENSE = ("stumpff", "inv3", "mm3", "ldl_inertia", "lu_factor", "lu_solve", "segment_blocks", "full6", "state_change",
         "iteration_converged", "iteration_start")
#: The load solve's helpers on many load sets (tmm_core.kernels_maps).
MAPS = ("sweep_member", "copy_sweep", "maps_scratch", "solve_loads_many")
#: The march's helpers (tmm_core.kernels).
MARCH = ("history", "advance", "shape_products", "affine", "anderson_coefficients")
#: The reduced revolution's helpers (tmm_core.kernels_reduced).
REDUCED = ("dot", "lu_factor", "lu_solve", "subtract_rows", "lu_solve_many", "second_order", "stage_states",
           "newton_matrix")

_ENTRY: dict = {}        # the one registry: a stage's (or a single kernel's) compiled entry points


def _bind(jit, module, names, into=()) -> None:
    """Compile ``module.<name>`` for each name and put it in ``module`` and in every module of
    ``into`` that refers to it by that name (a ``from ... import`` or an alias)."""
    for name in names:
        compiled = jit(getattr(module, name))
        for target in (module, *into):
            if target is module or hasattr(target, name):
                setattr(target, name, compiled)


def static_solve():
    """``(solve_range, iteration_start)``: :func:`tmm_core.kernels_static.solve_range` compiled
    without the GIL (the Python driver runs a batch's parts on threads), with the factorization,
    the load solves and the dense helpers bound where they are called, and the beam-column
    iteration's start (:func:`tmm_core.kernels_dense.iteration_start`)."""
    if "static" not in _ENTRY:
        numba = numba_module()
        jit = numba.njit(cache=True, error_model="numpy")
        _bind(jit, kernels_dense, DENSE, into=(kernels_factor, kernels_static))
        _bind(jit, kernels_factor, ("factor_configuration", "factor_scratch"), into=(kernels_static, kernels_factored))
        _bind(jit, kernels_maps, MAPS, into=(kernels_static,))
        _bind(jit, kernels_static, ("solve_loads",), into=(kernels_factored,))
        _bind(numba.njit(cache=True, error_model="numpy", nogil=True), kernels_static, ("solve_range",))
        _ENTRY["static"] = kernels_static.solve_range, kernels_dense.iteration_start
    return _ENTRY["static"]


def factored():
    """``(factor_range, factored_solve)`` of :mod:`tmm_core.kernels_factored`, compiled (the
    stored factorizations of a range of a batch, without the GIL; the solve on one of them,
    inlined where it is called)."""
    if "factored" not in _ENTRY:
        numba = numba_module()
        static_solve()                               # the factorization and the load solve it calls
        _bind(numba.njit(cache=True, error_model="numpy", nogil=True), kernels_factored, ("factor_range",))
        _bind(numba.njit(cache=True, error_model="numpy", inline="always"), kernels_factored, ("factored_solve",),
              into=(kernels,))
        _ENTRY["factored"] = kernels_factored.factor_range, kernels_factored.factored_solve
    return _ENTRY["factored"]


def march():
    """:func:`tmm_core.kernels.march`, compiled with its helpers and the stored-factorization solve."""
    if "march" not in _ENTRY:
        numba = numba_module()
        factored()
        # Reassociation lets LLVM vectorise the map products (dot-product reductions); no other
        # fast-math flag: the march tests for non-finite values.
        jit = numba.njit(cache=True, fastmath={"reassoc", "contract"})
        _bind(jit, kernels, MARCH)
        _ENTRY["march"] = jit(kernels.march)
    return _ENTRY["march"]


def reduced_revolution():
    """:func:`tmm_core.kernels_reduced.revolution`, compiled with its helpers."""
    if "reduced" not in _ENTRY:
        numba = numba_module()
        # error_model "numpy": a singular Newton matrix gives inf/nan (the step then fails to
        # converge, as in the numpy path) instead of raising ZeroDivisionError in the kernel.
        jit = numba.njit(cache=True, error_model="numpy")
        _bind(jit, kernels_reduced, REDUCED)
        _ENTRY["reduced"] = jit(kernels_reduced.revolution)
    return _ENTRY["reduced"]


def single(function):
    """``function`` compiled alone (a kernel that calls no helper of its own module), once."""
    key = (function.__module__, function.__qualname__)
    if key not in _ENTRY:
        _ENTRY[key] = numba_module().njit(cache=True)(function)
    return _ENTRY[key]
