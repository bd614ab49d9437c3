"""Time-domain analysis of a linkage under a prescribed crank motion (transfer-matrix method).

The elastic motion adds inertia ``m (q_ddot + coupling)`` at every lumped mass (:mod:`tmm_core.ked`
gives the mass model and the rotating-frame terms). With an implicit integrator
(:mod:`tmm_core.integrators`) each step is a static solution of the instantaneous structure with a
"dynamic stiffness" ``m c_a`` at each mass and history loads (Shin Eq. 3.47).

The model is built once and frozen (:func:`tmm_core.discretization.discretize`: DOFs, masses,
segment operators, gauges and output layout, integrator, settings and backend); the stages are
functions of it: the configuration batches (:func:`tmm_core.batches.configurations`), the step
loads and one step (:mod:`tmm_core.time_step`), the march (:mod:`tmm_core.march`).

Public: :class:`TimeDomain`, the facade that builds the model (``model``) and delegates to the
stages (``configurations``, ``step_loads``, ``solve_step``, ``begin``, ``run``); the model's
fields read through it (``n_dof``, ``links``, ``outputs``, ...).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from .batches import configurations
from .discretization import DEFAULT_TERMS, MAX_STEP_DATA_BYTES, Discretization, discretize
from .errors import ConvergenceError, InputError, require_positive
from .ked import Coupling, CrankMotion, KEDResult
from .march import begin, quasi_static_start, rest_acceleration
from .mechanism import FourBarMechanism
from .post import Gauge
from .revolution import Revolution, aligned_change
from . import time_step

__all__ = ["TimeDomain", "time_domain", "RunOptions", "march_history"]

#: The model's fields and views that read through the facade (``td.n_dof`` is ``td.model.n_dof``).
MODEL_NAMES = frozenset(f for f in Discretization.__dataclass_fields__) | {
    "compiled", "compiled_factorization", "stack", "unstack", "link_factor", "kernel_model"}


class TimeDomain:
    """Time-domain analysis of a four-bar under a prescribed crank motion: the public facade of a
    frozen model (:attr:`model`, a :class:`tmm_core.discretization.Discretization` built once
    here) and the stages that take it.

    Parameters
    ----------
    mech : the mechanism (links carry their mass model, damping and viscoelastic law).
    integrator : 'newmark' (average acceleration) or 'houbolt' (Shin).
    coupling : rotating-frame terms, see :class:`Coupling`.
    beam_column : include the axial-force (beam-column) coupling of bending; False is linear
        theory (``axial_force='none'``).
    axial_force : how the axial force enters the bending equations when ``beam_column``:
        'dynamic' (default): the segments' nonlinear terms (:mod:`tmm_core.second_order`, as
        ``dynamic_terms`` chooses): the step's own axial force, including the axial shortening
        from bending, iterated within every step on the cached factorization; it agrees with
        geometrically exact beams near buckling (FE crank-rocker at 373 rpm, within a few per
        cent of exudyn where 'quasi_static' is 8-24 % off). A transient excursion past the static Euler load is
        integrated as long as the dynamic system stays positive definite.
        'quasi_static': the quasi-static (rigid-body) axial force of each crank position, fixed
        in the field matrices; linear per step and cheaper; good far from buckling.
    axial_tolerance, axial_iterations : relative tolerance and iteration limit of the 'dynamic'
        step iteration.
    dynamic_terms : the nonlinear terms of the 'dynamic' step: 'shortening' (axial shortening
        from bending) and 'axial_force' (the step's own axial force in the bending equations);
        both alone: the second-order (von Karman) segments; with both, 'corotational' (the
        default, :data:`tmm_core.discretization.DEFAULT_TERMS`) makes the segments exact in their
        rotation (every realisation of the step), and 'exact_strain' replaces their second-order
        strain by the geometrically exact axial strain alone (a prototype: numpy step only, so it
        runs the 'numpy' backend).
    backend : 'compiled' (the numba kernels of :mod:`tmm_core.compiled`), 'numpy' (the reference)
        or None (compiled where numba is installed): chosen once here, read by every stage
        (:func:`tmm_core.backend.choose_backend`).
    gravity : gravity vector [m/s^2] in the mechanism plane, or None.
    gauges : gauges whose strains are recorded.
    max_map_bytes : memory budget for the stored load-to-response maps or factorizations of a
        batch; above it each step runs the numpy Riccati load sweep instead (same result, slower).

    The model's fields (``n_dof``, ``links``, ``offsets``, ``segments``, ``gauges``, ``outputs``,
    ``integrator``, ``axial_force``, ``backend``, ...) and its views (``compiled``, ``stack``,
    ``unstack``, ``link_factor``) read through the facade (:data:`MODEL_NAMES`).
    """

    def __init__(self, mech: FourBarMechanism, *, integrator: str = "newmark", coupling: Coupling = Coupling(),
                 beam_column: bool = True, gravity=None, gauges: Sequence[Gauge] = (),
                 max_map_bytes: float = MAX_STEP_DATA_BYTES, axial_force: str = "dynamic", axial_tolerance: float = 1e-8,
                 axial_iterations: int = 60, dynamic_terms: tuple = DEFAULT_TERMS, backend: str | None = None):
        #: The frozen model every stage reads.
        self.model = discretize(mech, integrator=integrator, coupling=coupling, beam_column=beam_column,
                                gravity=gravity, gauges=gauges, max_map_bytes=max_map_bytes, axial_force=axial_force,
                                axial_tolerance=axial_tolerance, axial_iterations=axial_iterations,
                                dynamic_terms=dynamic_terms, backend=backend)

    def __getattr__(self, name):
        # Only reached for names the facade does not define: the model's fields and views.
        model = self.__dict__.get("model")
        if model is not None and name in MODEL_NAMES:
            return getattr(model, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    # -- the stages, on the model --------------------------------------------------------------
    def configurations(self, angle, speed, accel, dt, maps: bool | str = "auto", axial_force=None):
        """The configuration batch of the crank states: :func:`tmm_core.batches.configurations`."""
        return configurations(self.model, angle, speed, accel, dt, maps, axial_force)

    def step_loads(self, cfg, idx, h_a, h_v, *, rigid: bool = True, viscous=None):
        """A step's stacked local loads: :func:`tmm_core.time_step.step_loads`."""
        return time_step.step_loads(self.model, cfg, idx, h_a, h_v, rigid=rigid, viscous=viscous)

    def solve_step(self, cfg, k, loads, state, dt, axial_guess=None):
        """One time step: :func:`tmm_core.time_step.solve_step`."""
        return time_step.solve_step(self.model, cfg, k, loads, state, dt, axial_guess)

    def kernel_data(self, cfg):
        """What the compiled march reads of a batch: :func:`tmm_core.time_step.kernel_data`."""
        return time_step.kernel_data(self.model, cfg)

    def rest_acceleration(self, loads, motion):
        """Accelerations from rest: :func:`tmm_core.march.rest_acceleration`."""
        return rest_acceleration(self.model, loads, motion)

    def quasi_static_start(self, th, w, a, dt):
        """The quasi-static initial state: :func:`tmm_core.march.quasi_static_start`."""
        return quasi_static_start(self.model, th, w, a, dt)

    # -- marching -----------------------------------------------------------------------------
    def begin(self, dt: float, angle: float, speed: float, acceleration: float = 0.0, *, start: str = "rest",
              initial: Mapping[str, np.ndarray] | None = None):
        """Start an incremental march at a crank state (step ``dt`` [s]): :func:`tmm_core.march.begin`."""
        return begin(self.model, dt, angle, speed, acceleration, start=start, initial=initial)

    def run(self, crank: CrankMotion, *, start: str = "rest", steady_tol: float | None = None,
            min_revolutions: int = 2, record_displacements: bool = True,
            callback: Callable[[int, float], bool] | None = None, chunk: int = 720,
            initial: Mapping[str, np.ndarray] | None = None) -> KEDResult:
        """March through the crank history: :func:`march_history` with these :class:`RunOptions`."""
        return march_history(self.model, crank, RunOptions(start, steady_tol, min_revolutions, record_displacements,
                                                           callback, chunk, initial))


@dataclass(frozen=True)
class RunOptions:
    """How :func:`march_history` marches a crank history.

    ``start``: 'rest' (zero elastic state, Shin) or 'quasi_static' (elastic state of the
    quasi-static solution at the first positions). ``steady_tol``: stop when the
    revolution-to-revolution change of the drive torque and gauge strains, relative to their
    peak-to-peak, falls below it (needs a constant-speed history); the change is reported;
    checked from revolution ``min_revolutions``. ``record_displacements``: keep the node
    displacements of every step. ``callback(step, t)`` returning False stops the run early
    (partial results kept; the steps are then marched one by one). ``chunk``: configurations
    factorized at a time of a history that is not periodic. ``initial``: explicit initial state
    instead of ``start``: ``{'d', 'v', 'a', 'previous'}`` with stacked local node vectors (see
    :attr:`tmm_core.discretization.Discretization.offsets`) and ``previous = (d_-1, d_-2)``."""

    start: str = "rest"
    steady_tol: float | None = None
    min_revolutions: int = 2
    record_displacements: bool = True
    callback: Callable[[int, float], bool] | None = None
    chunk: int = 720
    initial: Mapping[str, np.ndarray] | None = None


def march_history(model: Discretization, crank: CrankMotion, options: RunOptions = RunOptions()) -> KEDResult:
    """March ``model`` through the crank history ``crank`` (see :class:`RunOptions`): the outputs
    of every step (drive torque [N m], gauge strains) and the node displacements [m, rad]."""
    dt = crank.dt
    n_steps = len(crank.t)
    N = crank.steps_per_revolution()
    if options.steady_tol is not None:
        require_positive("steady_tol", options.steady_tol)
        if N is None:
            raise InputError("steady_tol needs a constant-speed crank history with a whole number of steps per "
                             "revolution")
    march = begin(model, dt, crank.angle[0], crank.speed[0], crank.acceleration[0], start=options.start,
                  initial=options.initial)
    outputs = np.full((n_steps, march.n_out), np.nan)
    disp = np.full((n_steps, model.n_dof), np.nan) if options.record_displacements else None
    outputs[0] = march.out
    if disp is not None:
        disp[0] = march.z

    cfg, cfg_start, cfg_len = None, -1, 0
    steady, change, done = False, float("nan"), n_steps
    k = 1
    while k < n_steps:
        # Configurations are factorized in batches: one revolution when the history is periodic,
        # chunks of consecutive steps otherwise. Steps are marched in blocks that end at a
        # revolution (the steady-state check) or at the end of a chunk; one by one with a callback.
        if N is not None:
            if cfg is None:
                cfg = Revolution.build(model, crank.angle[:N], crank.speed[:N], crank.acceleration[:N], dt).batch
            end = min(n_steps, (k // N + 1) * N)
            indices = np.arange(k, end) % N
        else:
            if cfg is None or k >= cfg_start + cfg_len:
                cfg_start, cfg_len = k, min(options.chunk, n_steps - k)
                sl = slice(k, k + cfg_len)
                cfg = configurations(model, crank.angle[sl], crank.speed[sl], crank.acceleration[sl], dt)
            end = cfg_start + cfg_len
            indices = np.arange(k, end) - cfg_start
        if options.callback is not None:
            indices, end = indices[:1], k + 1
        zs, outs = march.step_many(cfg, indices, record_z=disp is not None)
        outputs[k:end] = outs
        if disp is not None:
            disp[k:end] = zs
        if not np.all(np.isfinite(outs)):
            bad = k + int(np.argmax(~np.all(np.isfinite(outs), axis=1)))
            raise ConvergenceError(f"time-domain solution became non-finite at step {bad} (t = {crank.t[bad]:.6g} s); "
                                   "the step may be too large for the stiffest mode (reduce the step)")
        k = end
        last = k - 1
        if N is not None and last >= N and k % N == 0 and k // N >= options.min_revolutions:
            change = aligned_change(outputs[k - N:k], outputs[k - 2 * N:k - N])
            if options.steady_tol is not None and change < options.steady_tol:
                steady, done = True, k
                break
        if options.callback is not None and options.callback(last, float(crank.t[last])) is False:
            done = k
            break

    sl = slice(0, done)
    gauges = model.outputs.split(outputs[sl])
    displacements = {}
    if disp is not None:
        displacements = model.unstack(disp[sl])
    revs = (crank.angle[done - 1] - crank.angle[0]) / (2 * math.pi)
    return KEDResult(crank.t[sl], crank.angle[sl], crank.speed[sl], crank.acceleration[sl],
                     model.outputs.torque(outputs[sl]),
                     gauges, displacements, steady, change, abs(float(revs)), model.integrator.name,
                     {"dt_s": dt, "steps": done, "steps_per_revolution": N, "start": options.start,
                      "maps": cfg.maps is not None if cfg else None})


def time_domain(mech, crank: CrankMotion, **kw) -> KEDResult:
    """Convenience wrapper: ``TimeDomain(mech, ...).run(crank, ...)``; keyword arguments are split
    between the constructor and :meth:`TimeDomain.run`."""
    run_keys = {"start", "steady_tol", "min_revolutions", "record_displacements", "callback", "chunk"}
    run_kw = {k: v for k, v in kw.items() if k in run_keys}
    init_kw = {k: v for k, v in kw.items() if k not in run_keys}
    return TimeDomain(mech, **init_kw).run(crank, **run_kw)
