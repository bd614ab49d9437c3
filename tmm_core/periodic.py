"""Periodic steady state of the kineto-elastodynamic equations in one solve, and their Floquet
multipliers.

At constant crank speed the time-discrete equations of :class:`tmm_core.TimeDomain` are linear
with coefficients periodic in the crank angle: one revolution of N steps maps the integrator state
x (displacements, velocities, accelerations, ...) affinely, ``x_N = Phi x_0 + c``. Shooting: the
revolution is marched once for the affine part and for every unit state at the same time (one
batched march of n_state + 1 columns), and the periodic state solves ``(I - Phi) x_0 = c``. It is
the exact limit of time marching with the same integrator and step (the discrete map's fixed
point), so no transient has to die out; near a resonance and with light damping this replaces
many revolutions by one.

The eigenvalues of ``Phi`` are the Floquet multipliers of the discrete system over a revolution:
a multiplier outside the unit circle means a growing (parametrically resonant) response. They
carry the integrator's numerical damping (generalized-alpha damps the highest modes).

With the second-order step (``axial_force = 'dynamic'``, :mod:`tmm_core.second_order`) the
revolution map is nonlinear. Newton shooting then solves ``F(x_0) = x_0``: each iteration
marches the nonlinear revolution once from the current guess (the same step as time marching)
and the linearized revolution for the monodromy matrix (one batched march of every unit state
through the step's exact Jacobian), starting from the periodic solution of the linear
(quasi-static axial force) model, whose Phi is the first Jacobian. The multipliers are those of
the linearization about the periodic orbit; for an orbit reached from a guess, where that can be
trusted, the dominant ones read off a few revolutions (:func:`_read_multipliers`).

The linearized revolutions run in compiled kernels (:mod:`tmm_core.compiled.periodic`; 0.05 s for
the linear pass and 0.14 s per monodromy on the FE rig, 216 states, 720 steps); the numpy code
here is their reference (``TimeDomain(backend="numpy")``, the default without numba).

Owns: periodic steady state and Floquet multipliers. Boundaries: the step is tmm_core's public
step API.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .compiled import binding as kernel_binding, periodic as compiled_periodic
from .anderson import AndersonOptions, FixedPoint, anderson, block_weights, residual_of
from .errors import ConvergenceError, InputError, TMMError
from .batches import configurations
from .discretization import Discretization, HoldsModel, as_model
from .ked import CrankMotion
from .march import begin
from .revolution_dmd import dominant_multipliers
from .second_order import corotational_linearization, linearization
from .time_step import kernel_data, step_loads

STATE_KEYS = {"newmark": ("d", "v", "a"), "generalized_alpha": ("d", "v", "a", "acc"), "houbolt": ("d", "d1", "d2")}

#: Reading the multipliers of an orbit reached from a guess (:func:`_read_multipliers`): at most
#: this many plain revolutions from a perturbation of the orbit of this size (relative to each
#: state block's largest entry); changes below ``READ_FLOOR`` of the perturbation are not read
#: (the second-order step's axial iteration leaves the revolution map a rounding of about 1e-8 of
#: the state, which a fit would read as a slowly decaying mode); at least ``READ_MIN_CHANGES``
#: changes must be read (with four, the FE rig's largest multiplier came out up to 2e-3 off the
#: monodromy's; with five or more, within 2e-5 from 210 to 420 rpm), and from a largest multiplier
#: of ``READ_TRUSTED_BELOW`` the full monodromy is computed instead (a verdict near the unit
#: circle must not rest on a fit).
READ_REVOLUTIONS, READ_PERTURBATION, READ_FLOOR, READ_MIN_CHANGES, READ_TRUSTED_BELOW = 8, 1e-3, 1e-4, 5, 0.9


@dataclass
class PeriodicResult:
    """One steady revolution: ``angle`` [rad] and outputs at the N steps (the first sample is the
    state after one step), drive torque [N m], gauges ``{name: (bending, axial)}``, the Floquet
    ``multipliers`` (descending modulus; all of the monodromy's, or the dominant few where
    ``info["multipliers"]`` says they were read off revolutions) and ``residual`` (relative change of the state over a
    revolution marched from the periodic state: the solve's own check) and the periodic ``state``
    at the start angle (the solver's stacked state vector, mixed units: m, m/s, m/s^2; a nearby
    speed's solve takes as ``initial_state``)."""

    t: np.ndarray
    angle: np.ndarray
    drive_torque: np.ndarray
    gauges: dict
    multipliers: np.ndarray
    residual: float
    info: dict
    state: np.ndarray | None = None


def _batched_step(model: Discretization, cfg, idx, state, dt, forced: bool = True):
    """One linear time step for a batch of states: every array in ``state`` is (M, n_dof).
    ``forced=False``: without the rigid-body loads and the maps' constant parts (homogeneous)."""
    h_a, h_v = model.integrator.history(state, dt)
    loads = step_loads(model, cfg, idx, h_a, h_v, rigid=forced)
    maps = cfg.maps
    z = loads @ maps.Z[idx].T + (maps.z0[idx] if forced else 0.0)
    out = loads @ maps.O[idx].T + (maps.o0[idx] if forced else 0.0)
    return model.integrator.advance(state, z, dt), z, out


@dataclass(frozen=True)
class ShootingOptions:
    """Newton shooting of the second-order model: ``tolerance``, the relative change of the state
    over a revolution at which it stops (also the Anderson revolutions' from a guess), and the most
    Newton ``iterations``."""

    tolerance: float = 1e-7
    iterations: int = 15


def periodic_steady_state(source: Discretization | HoldsModel, speed_rad_s: float, *, step_s: float | None = None,
                          step_deg: float | None = None, start_angle: float = 0.0,
                          shooting: ShootingOptions = ShootingOptions(), crank: CrankMotion | None = None,
                          initial_state: np.ndarray | None = None) -> PeriodicResult:
    """Periodic response of the model ``source`` (a :class:`tmm_core.discretization.Discretization`
    or a :class:`tmm_core.TimeDomain`, whose model is taken) at constant crank ``speed_rad_s``
    [rad/s]; the step must divide a revolution (as for a constant-speed :class:`CrankMotion`).
    ``shooting``: Newton shooting's tolerance and iterations (:class:`ShootingOptions`; second-order model).

    ``crank``: instead of the constant speed, one period of a periodic crank history (a crank
    whose speed fluctuates within the revolution): N + 1 samples whose last is one revolution
    after the first (angle advanced by 2 pi, same speed and acceleration); ``speed_rad_s`` and
    the step arguments are then unused.

    ``initial_state``: a guess of the periodic state (as :attr:`PeriodicResult.state`: the stacked
    integrator state at the start angle, e.g. the previous speed's orbit in a sweep). The
    second-order model then iterates Anderson-accelerated revolutions from it
    (:mod:`tmm_core.anderson`) instead of the linear model's shooting pass (a 217-column
    linearized revolution) and the Newton monodromies; when they stall it solves as without a
    guess, and where that finds no orbit, by Newton shooting from their best iterate (the
    branch carried on, often through unstable orbits near a fold); the tolerance is the same. The
    multipliers are those of the full monodromy at the converged orbit, except for an orbit the
    revolutions from the guess reached: there the dominant ones are read off a few plain
    revolutions (:func:`_read_multipliers`) where that reading can be trusted. The linear model
    ignores the guess (its solve is direct)."""
    model = as_model(source)
    if any(link.viscoelastic is not None for link in model.links):
        raise InputError("the periodic solver does not carry the viscoelastic (SLS) history states; use time marching")
    if model.strain_measure == "exact":
        # Its linearized revolution (Newton's Jacobian, the Floquet multipliers) differentiates
        # the second-order and the co-rotational pseudo-loads only.
        raise InputError(f"periodic solver: the segments' exact strain (dynamic_terms {model.dynamic_terms!r}) "
                         "is not in its linearized revolution; march in time")
    keys = STATE_KEYS.get(model.integrator.name)
    if keys is None:
        raise InputError(f"periodic solver: unsupported integrator {model.integrator.name!r}")
    crank, N = _one_period(crank, speed_rad_s, step_s, step_deg, start_angle)
    dt = crank.dt
    cfg = configurations(model, crank.angle[:N], crank.speed[:N], crank.acceleration[:N], dt, maps=True)
    if cfg.maps is None:
        raise InputError("periodic solver: the load-to-response maps exceed the memory budget (max_map_bytes)")
    ns = len(keys) * model.n_dof
    info = {"dt_s": dt, "steps_per_revolution": N, "state_size": ns}
    revolution = _Revolution(model, cfg, keys, N, dt)
    solved = fp = None
    if model.axial_force == "dynamic" and initial_state is not None:
        fp = _from_guess(revolution, initial_state, shooting.tolerance, info)
        solved = (fp.x, fp.image, fp.revolutions) if fp.converged else None
    if solved is None:
        x0, Phi = _linear_solution(revolution)
    if model.axial_force == "dynamic":
        if solved is None:
            try:
                solved = _from_linear(revolution, x0, Phi, shooting.tolerance, shooting.iterations, info)
            except ConvergenceError as exc:
                solved = _past_linear_start(revolution, fp, shooting, info, exc)
        x0, (xN, trajectory, outs, residual), info["newton_iterations"] = solved
        multipliers = _read_multipliers(revolution, x0, info) if fp is not None and fp.converged else None
        if multipliers is None:
            multipliers = np.linalg.eigvals(revolution.monodromy(trajectory))
    else:
        # One revolution from the periodic state, for the outputs and as a check.
        st = _state(model, keys, x0[None, :])
        outs = []
        for k in range(1, N + 1):
            st, _, out = _batched_step(model, cfg, k % N, st, dt)
            outs.append(out[0])
        xN = np.concatenate([st[k][0] for k in keys])
        residual = residual_of(x0, xN)
        multipliers = np.linalg.eigvals(Phi)
    multipliers = multipliers[np.argsort(-np.abs(multipliers))]
    outs = np.array(outs)
    return PeriodicResult(crank.t[1:N + 1], crank.angle[1:N + 1], model.outputs.torque(outs), model.outputs.split(outs),
                          multipliers, residual, info, x0)


@dataclass(frozen=True)
class _Revolution:
    """What every revolution of one periodic solve marches: the model, its configurations over the
    revolution (``cfg``, with maps), the state's arrays (``keys``), N steps of ``dt`` [s]."""

    model: Discretization
    cfg: object
    keys: tuple
    N: int
    dt: float

    def monodromy(self, trajectory):
        """The monodromy of the revolution linearized about ``trajectory`` (compiled kernels or the
        numpy reference)."""
        linearized = _compiled_monodromy if self.model.compiled else _monodromy
        return linearized(self.model, self.cfg, self.keys, trajectory, self.dt)


def _one_period(crank, speed_rad_s, step_s, step_deg, start_angle):
    """``(crank, N)``: the constant-speed revolution at ``speed_rad_s`` [rad/s] with the given step
    [s or deg], or the given periodic ``crank`` history checked to span one period."""
    if crank is None:
        crank = CrankMotion.constant_speed(speed_rad_s, step_s=step_s, step_deg=step_deg, revolutions=1.0,
                                           start_angle=start_angle)
        N = crank.steps_per_revolution()
        if N is None:
            raise InputError("the step must divide a revolution into a whole number of steps")
        return crank, N
    N = len(crank.t) - 1
    turn = abs(crank.angle[N] - crank.angle[0])
    if (abs(turn - 2 * math.pi) > 1e-9 * 2 * math.pi or
            not np.isclose(crank.speed[N], crank.speed[0], rtol=1e-6, atol=1e-9) or
            not np.isclose(crank.acceleration[N], crank.acceleration[0], rtol=1e-6,
                           atol=1e-6 * max(1.0, float(np.max(np.abs(crank.acceleration)))))):
        raise InputError("periodic solver: the crank history must span exactly one period (last sample one "
                         "revolution after the first, with the same speed and acceleration)")
    return crank, N


def _linear_solution(rev: _Revolution):
    """The linear step's periodic state and monodromy ``(x0, Phi)``: ``x_N = Phi x_0 + c`` over a
    revolution, ``(I - Phi) x_0 = c``."""
    model, cfg, keys, N, dt = rev.model, rev.cfg, rev.keys, rev.N, rev.dt
    ns = len(keys) * model.n_dof
    if model.compiled:
        Phi, c = compiled_periodic.linear_shooting(kernel_binding.linearized(), model, kernel_data(model, cfg), keys,
                                                   N, dt)
    else:
        # x_N = Phi x_0 + c: the zero state with the forcing (c) and the unit states without it
        # (Phi; differencing forced unit states with c lost up to 1e-4 in blocks of small entries).
        forced, state = _state(model, keys, np.zeros((1, ns))), _state(model, keys, np.eye(ns))
        for k in range(1, N + 1):
            forced, _, _ = _batched_step(model, cfg, k % N, forced, dt)
            state, _, _ = _batched_step(model, cfg, k % N, state, dt, forced=False)
        c = np.concatenate([forced[k][0] for k in keys])
        Phi = np.concatenate([state[k] for k in keys], axis=1).T
    return np.linalg.solve(np.eye(ns) - Phi, c), Phi


def _from_linear(rev: _Revolution, x0, Phi, tolerance, iterations, info):
    """Newton shooting on the nonlinear revolution map from the linear model's solution ``x0``.
    The monodromy (the expensive part) is kept while it converges fast (chord iterations) and
    recomputed at the current orbit when the residual falls by less than a factor 4. The first
    Jacobian is the linear model's I - Phi (known: saves a monodromy where the second-order terms
    are mild). If the residual then grows (near buckling, residuals of order 1), Newton restarts
    from the linear solution with the monodromy there: the iterates are those of plain Newton, so
    no speed it solves is lost. Returns ``(x0, shot, revolutions)``."""
    shot = _shoot(rev.model, rev.cfg, rev.keys, x0, rev.N, rev.dt, 1)
    solved = _newton(rev, x0, shot, np.eye(len(x0)) - Phi, tolerance, iterations, strict=True)
    info["restarted"] = solved is None
    if solved is None:
        solved = _newton(rev, x0, shot, None, tolerance, iterations, strict=False)
    return solved


def _from_guess(rev: _Revolution, guess, tolerance, info) -> FixedPoint:
    """Anderson-accelerated revolutions from ``guess`` (:func:`tmm_core.anderson.anderson`): the
    fixed point, converged or the best iterate of a stall."""
    keys = rev.keys

    def revolve(x):
        shot = _shoot(rev.model, rev.cfg, keys, x, rev.N, rev.dt, 1)
        return shot[0], shot

    x0 = np.asarray(guess, dtype=float)
    fp = anderson(revolve, x0, block_weights(x0, len(keys)), AndersonOptions(tolerance))
    info["anderson_revolutions"] = fp.revolutions
    info["start"] = "guess" if fp.converged else "linear"
    return fp


def _read_multipliers(rev: _Revolution, x0, info) -> np.ndarray | None:
    """The dominant Floquet multipliers of the orbit ``x0`` read off plain revolutions from a fixed
    perturbation of it (:func:`tmm_core.revolution_dmd.dominant_multipliers` on the state, each
    block scaled by its largest entry), at a third of the full monodromy's cost or less. None
    (compute the monodromy) where the reading is not to be trusted: a revolution that fails, a
    perturbation that dies before :data:`READ_MIN_CHANGES` changes are read (an orbit with
    multipliers below about 0.06 on the FE rig; the revolutions stop as soon as it is clear), or
    a largest multiplier from :data:`READ_TRUSTED_BELOW` up."""
    weights = block_weights(x0, len(rev.keys))
    floor = READ_FLOOR * READ_PERTURBATION
    # A fixed perturbation (seeded): the same answer from the same orbit every time.
    x = x0 + READ_PERTURBATION * np.random.default_rng(0).standard_normal(len(x0)) / weights
    snapshots = [x * weights]
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            for _ in range(READ_REVOLUTIONS):
                x = _revolution(rev.model, rev.cfg, rev.keys, x, rev.N, rev.dt)[0]
                snapshots.append(x * weights)
                if np.abs(snapshots[-1] - snapshots[-2]).max() <= floor:
                    break
    except (TMMError, np.linalg.LinAlgError):
        return None
    mu, read = dominant_multipliers(np.array(snapshots), floor=floor)
    if read < READ_MIN_CHANGES or not np.all(np.isfinite(mu)) or abs(mu[0]) >= READ_TRUSTED_BELOW:
        return None
    info["multipliers"] = f"read off {read + 1} revolutions"
    return mu


def _past_linear_start(rev: _Revolution, fp: FixedPoint | None, shooting: ShootingOptions, info, error):
    """Where the linear start finds no orbit (``error``), Newton shooting from the best iterate of
    the stalled Anderson revolutions ``fp``: the branch continued from the previous speed, often an
    unstable orbit near a fold. Tried only after the linear start, so that where that finds an
    orbit the answer is the one a solve without a guess gives (near a fold a stable and an
    unstable orbit coexist: at 400 rpm on the FE rig, 10 rpm from the previous speed, Newton from
    the guess converged to the unstable one). Raises ``error`` when it does not converge either."""
    if fp is None or fp.image is None:
        raise error
    try:
        solved = _newton(rev, fp.x, fp.image, None, shooting.tolerance, shooting.iterations, strict=True)
    except ConvergenceError:
        solved = None
    if solved is None:
        raise error
    info["start"] = "guess, Newton"
    return solved


def _shoot(model: Discretization, cfg, keys, x0, N, dt, it):
    """Revolution ``it`` of Newton shooting from ``x0``: ``(xN, trajectory, outputs, residual)``."""
    try:
        # A revolution that leaves the model's range overflows on its way to the error below, which
        # is the report (numpy's warnings went to every sweep worker's stderr).
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            xN, trajectory, outs = _revolution(model, cfg, keys, x0, N, dt)
    except (TMMError, np.linalg.LinAlgError) as exc:     # e.g. a singular refactorization of a step
        raise ConvergenceError(f"periodic solver: Newton shooting left the range of the model at iteration "
                               f"{it} ({exc}); the response may not be periodic at this speed (march in "
                               "time instead)") from None
    return xN, trajectory, outs, residual_of(x0, xN)


def _newton(rev: _Revolution, x0, shot, jacobian, tolerance, iterations, strict):
    """Newton shooting from ``x0`` whose revolution ``shot`` (:func:`_shoot`) is marched, with
    ``jacobian`` (None: the monodromy at ``x0``) kept while the residual falls 4x per iteration.
    Returns ``(x0, shot, revolutions)`` at convergence. ``strict``: None instead of an error, and
    as soon as the residual grows."""
    model, cfg, keys, N, dt = rev.model, rev.cfg, rev.keys, rev.N, rev.dt
    last = math.inf
    for it in range(1, iterations + 1):
        xN, trajectory, _, residual = shot
        if residual < tolerance:
            return x0, shot, it
        if it == iterations or (strict and residual > last):
            break
        if jacobian is None or residual > 0.25 * last:
            jacobian = np.eye(len(x0)) - rev.monodromy(trajectory)
        last = residual
        x0 = x0 + np.linalg.solve(jacobian, xN - x0)
        try:
            shot = _shoot(model, cfg, keys, x0, N, dt, it + 1)
        except ConvergenceError:
            if strict:
                return None
            raise
    if strict:
        return None
    raise ConvergenceError(f"periodic solver: Newton shooting did not converge in {iterations} "
                           f"iterations (last relative residual {residual:.3g})")


def _state(model: Discretization, keys, X):
    """Integrator state from stacked state vectors ``X`` (..., len(keys) * n_dof)."""
    n = model.n_dof
    st = {k: X[..., j * n:(j + 1) * n].copy() for j, k in enumerate(keys)}
    zero = st["d"] * 0
    full = model.integrator.initial(st["d"], st.get("v", zero), st.get("a", zero),
                                    (st.get("d1", zero), st.get("d2", zero)))
    full.update(st)
    return full


def _revolution(model: Discretization, cfg, keys, x0, N, dt):
    """One nonlinear (second-order) revolution from the state vector ``x0``: the final state
    vector, the trajectory ``(idx, z, v, P)`` per step for the linearization, and the outputs."""
    state = _state(model, keys, x0)
    _, c_v = model.integrator.coefficients(dt)
    march = begin(model, dt, *cfg.crank.at(0),
                  initial={"d": state["d"], "v": state["v"], "a": state["a"],
                           "previous": (state.get("d1", state["d"]), state.get("d2", state["d"]))},
                  outputs_at_start=False)
    march.state = state
    indices = np.arange(1, N + 1) % N
    zs, outs, Ps = march.step_many(cfg, indices, record_axial=True)
    # The trajectory for the linearization: displacements, velocities (v = c_v z + h_v, the
    # history from the state before each step) and axial forces per step.
    if model.compiled:
        # The same recursion compiled (in Python it took 2/3 of the revolution's time).
        vs = compiled_periodic.trajectory_velocities(kernel_binding.linearized(), model.integrator, state, zs, dt)
        trajectory = [(idx, zs[j], vs[j], Ps[j]) for j, idx in enumerate(indices)]
    else:
        trajectory, st = [], state
        for j, idx in enumerate(indices):
            _, h_v = model.integrator.history(st, dt)
            st = model.integrator.advance(st, zs[j], dt)
            trajectory.append((idx, zs[j], c_v * zs[j] + h_v, Ps[j]))
    return np.concatenate([march.state[k] for k in keys]), trajectory, list(outs)


def _monodromy(model: Discretization, cfg, keys, trajectory, dt):
    """Monodromy matrix of the second-order step linearized about ``trajectory``: every unit
    state marched through one revolution in one batch, each step a dense solve of the step's
    Jacobian in (displacements, segment axial forces)."""
    n = model.n_dof
    seg = model.segments
    n_seg = len(seg.length)
    _, c_v = model.integrator.coefficients(dt)
    linearize = corotational_linearization if model.strain_measure == "corotational" else linearization
    # J mixes metres and newtons (condition ~1e13 on the FE rig, ~1e5 with the axial-force
    # unknowns and equations scaled by EA/L): unscaled, the solve loses ~1e-10 per step.
    scale = np.concatenate([np.ones(n), seg.stiffness])
    damping = np.zeros((n_seg, n))                     # d(damping part of P)/d(velocity history)
    damping[np.arange(n_seg), seg.end] += seg.beta * seg.stiffness
    damping[np.arange(n_seg), seg.start] -= seg.beta * seg.stiffness
    state = _state(model, keys, np.eye(len(keys) * n))
    maps = cfg.maps
    for idx, z, v, P in trajectory:
        h_a, h_v = model.integrator.history(state, dt)
        dL = step_loads(model, cfg, idx, h_a, h_v, rigid=False)
        f_z, f_P, f_h, F_z, F_h = linearize(seg, n, c_v, z, v, P, cfg.P0[idx])
        Z, A = maps.Z[idx], maps.A[idx]
        J = np.block([[np.eye(n) - Z @ f_z, -Z @ f_P], [-(A @ f_z + F_z), np.eye(n_seg) - A @ f_P]])
        L = dL + h_v @ f_h.T
        rhs = np.concatenate([L @ Z.T, L @ A.T + h_v @ (damping + F_h).T], axis=1)
        y = np.linalg.solve(J * scale / scale[:, None], rhs.T / scale[:, None]).T
        state = model.integrator.advance(state, y[:, :n], dt)
    return np.concatenate([state[k] for k in keys], axis=1).T


def _compiled_monodromy(model: Discretization, cfg, keys, trajectory, dt):
    """:func:`_monodromy` in the compiled kernels (:func:`tmm_core.compiled.periodic.monodromy`),
    on the batch's compiled-march arrays (the batch must have its maps)."""
    return compiled_periodic.monodromy(kernel_binding.linearized(), model, kernel_data(model, cfg), keys, trajectory,
                                       dt)


def floquet_multipliers(A, period: float, n: int, rtol: float = 1e-10) -> np.ndarray:
    """Floquet multipliers of the continuous linear periodic system x' = A(t) x over one
    ``period``: eigenvalues of the monodromy matrix (the fundamental solution at the period)."""
    def rhs(t, y):
        return (A(t) @ y.reshape(n, n)).ravel()
    sol = solve_ivp(rhs, (0.0, period), np.eye(n).ravel(), method="DOP853", rtol=rtol, atol=rtol)
    if not sol.success:
        raise ConvergenceError(f"Floquet integration failed: {sol.message}")
    M = sol.y[:, -1].reshape(n, n)
    mu = np.linalg.eigvals(M)
    return mu[np.argsort(-np.abs(mu))]


def mathieu_multipliers(delta: float, epsilon: float, damping: float = 0.0) -> np.ndarray:
    """Multipliers of the Mathieu equation x'' + 2 zeta x' + (delta + epsilon cos t) x = 0 over
    its period 2 pi (the single-mode reduction of a linkage whose stiffness varies with the crank
    angle)."""
    def A(t):
        return np.array([[0.0, 1.0], [-(delta + epsilon * math.cos(t)), -2.0 * damping]])
    return floquet_multipliers(A, 2 * math.pi, 2)


#: The leading Floquet multiplier counts as real when its imaginary part is below this fraction
#: of its modulus (a real multiplier of a real monodromy matrix has round-off imaginary parts).
REAL_MULTIPLIER_RTOL = 1e-6
#: What an unstable periodic orbit's leading multiplier says (Floquet theory of a periodic orbit
#: continued in a parameter, here the crank speed).
ORBIT_KINDS = {
    "saddle": "a real multiplier above +1: the orbit lies on the unstable branch of a fold (saddle-node) or of a "
              "symmetry-breaking bifurcation, and a march at this speed leaves it",
    "period doubling": "a real multiplier below -1: a march at this speed leaves the orbit with a deviation that "
                       "alternates from one revolution to the next (period doubling)",
    "torus": "a complex pair outside the unit circle (Neimark-Sacker): a march at this speed leaves the orbit with a "
             "deviation modulated at a frequency of its own (quasi-periodic at first)",
}


def orbit_stability(multipliers) -> dict:
    """Stability of a periodic orbit from its Floquet ``multipliers`` (any order): ``{"stable":
    all |mu| <= 1, "mu_max": the largest |mu|, "multiplier": (real, imaginary) of that multiplier,
    "kind": None for a stable orbit, else a key of :data:`ORBIT_KINDS`}``. A multiplier on the unit
    circle counts as stable (the boundary of the stability chart)."""
    mu = np.asarray(multipliers, dtype=complex)
    lead = complex(mu[int(np.argmax(np.abs(mu)))])
    modulus = abs(lead)
    stable = bool(modulus <= 1.0)
    kind = None
    if not stable:
        if abs(lead.imag) > REAL_MULTIPLIER_RTOL * modulus:
            kind = "torus"
        else:
            kind = "saddle" if lead.real > 0 else "period doubling"
    return {"stable": stable, "mu_max": float(modulus), "multiplier": (lead.real, lead.imag), "kind": kind}
