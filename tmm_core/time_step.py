"""The solution of one time step of a model (:class:`tmm_core.discretization.Discretization`;
numpy reference path), and the loads it solves for.

A step is a static solution of the instantaneous structure with the step's inertia as node
stiffness (:mod:`tmm_core.ked`). Linear ('quasi_static', 'none'): one solve on the cached
factorization (a dense map product or a Riccati load sweep). Second order ('dynamic'): the
pseudo-loads of :mod:`tmm_core.second_order` iterated to convergence with Anderson mixing on the
cached factorization, and refactorized at the step's own axial forces when that fails.

Owns: :func:`step_loads`, :func:`solve_step` and :func:`kernel_data` (what the compiled march
reads of a batch), functions of the model. The compiled march (:mod:`tmm_core.compiled.march`)
does the same arithmetic and is checked against this code.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .anderson import anderson_coefficients
from .batches import configurations
from .compiled import time_step as compiled_time_step
from .discretization import Discretization
from .errors import ConvergenceError, InputError
from .ked import segment_forces
from .mechanism import torque_from_terms
from .post import gauge_strains
from .second_order import chord_lag, pseudo_loads, shape_products
from .step_data import select, terms_at
from .structure import solve_factored

#: Iterates mixed by the second-order step iteration. 8, not 4: a co-rotational segment couples its
#: stretch to its bending as 12 EI sin(b) / L^3, which the linear solver does not carry, so the
#: plain fixed point diverges on thick bars at fine meshes (Bahgat-Willmert at 32 segments); with 4
#: a 64-segment step needed up to 128 iterations, with 8 up to 65 (docs/light_damping.md).
ANDERSON_DEPTH = 8
#: Relative change of the segment axial forces at which the second-order step iteration stops
#: (with the displacements' Discretization.axial_tolerance). The axial force only feeds the
#: geometric stiffness: 1e-6 is ample, and its round-off floor, a difference of large nodal
#: forces, sits near 1e-8. The numpy step and the compiled march both read it.
AXIAL_FORCE_TOLERANCE = 1e-6
AXIAL_RESTARTS = 3          # refactorizations of a second-order step that does not converge


class StepSolution(NamedTuple):
    """The solution of one time step: node displacements ``z`` (n_dof, stacked local [m, rad]),
    the output row ``out`` (:class:`tmm_core.configuration_batch.OutputLayout`) and the segment
    axial forces ``axial`` (n_seg) [N, tension +] (None for a linear step without them)."""

    z: np.ndarray
    out: np.ndarray
    axial: np.ndarray | None


def step_loads(model: Discretization, cfg, idx, h_a, h_v, *, rigid: bool = True, viscous=None):
    """Stacked local nodal loads [N, N m] of a step at configuration ``idx`` of a batch, for the
    integrator history ``h_a, h_v`` (``(n_dof,)``, or ``(M, n_dof)`` for a batch of states):
    the configuration's D'Alembert loads (left out with ``rigid=False``: the state-dependent
    part alone, for linearizations), the inertia history, the Coriolis terms and the
    Kelvin-Voigt history; ``viscous = (q_sls, decay, gain, d)`` adds the standard-linear-solid
    history of a march. The one place that writes a step's loads."""
    m = model.m_vec
    loads = -m * (h_a + model.aM_vec * h_v)
    if rigid:
        loads = loads + cfg.rigid[idx]
    if model.coupling.coriolis:
        w = _node_omega(model, cfg, idx)
        # At u rows the w-velocity history of the same node, at w rows the u-velocity one.
        loads = loads + np.where(model.is_u, 2.0 * m * w * np.roll(h_v, -1, axis=-1), 0.0) \
            - np.where(model.is_w, 2.0 * m * w * np.roll(h_v, 1, axis=-1), 0.0)
    if model.has_kv:
        loads = loads - model.beta_node * (model.K_local @ h_v.T).T
    if viscous is not None:
        q_sls, decay, gain, d = viscous
        loads = loads - model.gather.T @ (decay * q_sls - gain * (model.seg_K @ (model.gather @ d)))
    return loads


def _node_omega(model: Discretization, cfg, idx):
    """The angular speed [rad/s] of each DOF's link at configuration ``idx`` of a batch."""
    motion = cfg.motion
    return np.concatenate([np.full(3 * l.n_nodes, float(motion.link(l.name).omega[idx]))
                           for l in model.links])


def solve_step(model: Discretization, cfg, k, loads, state, dt, axial_guess=None):
    """Displacements ``z``, outputs and segment axial forces [N] of one time step at
    configuration ``k`` of ``cfg`` for the stacked local ``loads`` (inertia history included)
    and the integrator ``state`` before the step. Linear for 'quasi_static' and 'none';
    for 'dynamic' the second-order pseudo-loads are iterated to convergence on the cached
    factorization, starting from ``axial_guess`` (e.g. the previous step's forces). Where the
    axial forces move far from the cached ones (a strong transient) that iteration can fail;
    the step is then factorized afresh at the latest axial forces and iterated again."""
    if model.axial_force != "dynamic":
        return _solve_one(model, cfg, k, loads)
    guess = axial_guess
    diag = (0, float("nan"), float("nan"))
    for attempt in range(AXIAL_RESTARTS + 1):
        if cfg.indefinite[k]:
            if guess is None:
                break
            result, guess_new = None, guess
        else:
            result, guess_new, diag = _iterate(model, cfg, k, loads, state, dt, guess)
        if result is not None:
            return result
        # Refactorize this step at the best axial forces known: the previous step's, then
        # the failed iteration's last finite estimate.
        guess = guess if attempt == 0 and guess is not None else guess_new
        if guess is None or not np.all(np.isfinite(guess)):
            break
        one = cfg.crank.take(k)
        try:
            cfg, k = configurations(model, one.angle, one.speed, one.accel, dt, maps=False, axial_force=guess[None]), 0
        except InputError:
            # The factorization at these axial forces overflows (a diverging march's forces, e.g.
            # 1e21 N): the step's failure, not a fault of the input.
            break
    crank = math.degrees(float(cfg.crank.angle[k]))
    reached = "" if guess is None else f", axial forces up to {float(np.max(np.abs(guess))):.3g} N"
    raise ConvergenceError(
        f"the nonlinear (axial_force 'dynamic') step did not converge at crank angle {crank:.6g} deg "
        f"(after {attempt} refactorizations; last relative changes: displacement {diag[1]:.3g}, axial "
        f"force {diag[2]:.3g}{reached}); the links are near a dynamic instability or the step is too large "
        "(reduce solver.tmm.step)")


def _iterate(model: Discretization, cfg, k, loads, state, dt, axial_guess):
    """The fixed-point iteration of :func:`solve_step` on one factorization: ``((z, out, P),
    None, (iterations, 0, 0))`` when converged, else ``(None, the last finite P of an iterate
    that was not diverging (None if none), (iterations, displacement change, axial-force
    change))``."""
    seg = model.segments
    c_a, c_v = model.integrator.coefficients(dt)
    _, h_v = model.integrator.history(state, dt)
    # Kelvin-Voigt: the physical axial force adds beta EA/L times the history part of the
    # relative axial velocity (the solver's own force carries EA (1 + beta c_v) (u1 - u0)/L).
    damping = seg.beta * seg.stiffness * (h_v[seg.end] - h_v[seg.start])
    P0 = cfg.P0[k]
    P = P0 if axial_guess is None else axial_guess
    z = state["d"] + dt * state["v"] + 0.5 * dt**2 * state["a"]
    # Anderson acceleration of the fixed point on x = (z, P L/EA): the axial force scaled to
    # the axial displacement it causes, so that both parts weigh alike in the mixing.
    n, to_len = len(z), seg.length / seg.EA
    x = np.concatenate([z, P * to_len])
    history, previous, last_finite = [], None, None
    scale_P = 1e-9 * float(np.max(seg.EA))
    dz = dP = float("nan")
    shorten, own_force = "shortening" in model.dynamic_terms, "axial_force" in model.dynamic_terms
    strain = model.strain_measure
    for it in range(model.axial_iterations):
        z, P = x[:n], x[n:] / to_len
        f, F, delta = pseudo_loads(seg, z, c_v * z + h_v, P if own_force else P0, P0, strain)
        if not np.all(np.isfinite(f)):
            # An iterate that overflowed (a diverging step): the step's report, not the structure's
            # refusal of non-finite node loads.
            break
        z_new, out, N = _solve_one(model, cfg, k, loads + f)
        P_new = N + damping + F
        if not (np.all(np.isfinite(z_new)) and np.all(np.isfinite(P_new))):
            break
        dz = float(np.max(np.abs(z_new - z))) / (float(np.max(np.abs(z_new))) + 1e-300)
        dP = float(np.max(np.abs(P_new - P))) / (float(np.max(np.abs(P_new))) + scale_P)
        if dz < model.axial_tolerance and dP < AXIAL_FORCE_TOLERANCE:
            if len(model.gauges) and shorten:
                # Gauge axial strain = the full axial strain, with the shortening from bending.
                delta = shape_products(seg, z_new)[0] if strain == "second_order" else \
                    pseudo_loads(seg, z_new, c_v * z_new + h_v, P_new, P0, strain)[2]
                out = out.copy()
                out[model.outputs.axial_columns] += model.gauge_shortening_strain(delta)
                if strain == "corotational":
                    # Gauge bending = the co-rotational segment's, not the linear one the solver holds.
                    out[model.outputs.bending_columns] += model.gauge_lag_strain(chord_lag(seg, z_new))
            return StepSolution(z_new, out, P_new), None, (it + 1, dz, dP)
        if dz > 1e3 or dP > 1e3:       # diverging: refactorize rather than iterate on
            break
        # The estimate a refactorization starts from: not a diverging one (refactorized at axial
        # forces of 1e258 N, a step reported a segment overflowing cosh, "split the link").
        last_finite = P_new
        gx = np.concatenate([z_new, P_new * to_len])
        r = gx - x
        if previous is not None:
            history.append((r - previous[0], gx - previous[1]))
            history = history[-ANDERSON_DEPTH:]
        previous = (r, gx)
        x = gx
        if history:
            dR = np.stack([h[0] for h in history], axis=1)
            dG = np.stack([h[1] for h in history], axis=1)
            gamma = anderson_coefficients(dR, r)
            if np.all(np.isfinite(gamma)):
                x = gx - dG @ gamma
            else:                       # an overflowing history: start the mixing afresh
                history = []
    return None, last_finite, (model.axial_iterations, dz, dP)


def _solve_one(model: Discretization, cfg, k, loads):
    """Response to the stacked local loads at configuration index k (map or sweep):
    ``(z, out, N)`` with ``N`` the solver's segment axial forces (None without them)."""
    maps = cfg.maps
    if maps is not None:
        N = maps.A[k] @ loads + maps.a0[k] if maps.A is not None else None
        return StepSolution(maps.Z[k] @ loads + maps.z0[k], maps.O[k] @ loads + maps.o0[k], N)
    node_loads = _node_loads(model, loads)
    whole = cfg.factor()
    if whole.batch[0] == 1:
        factor = whole
    else:
        # Selecting one configuration walks the whole factor (4 ms at 32 segments per link):
        # keep each selection (views, no copies) for the following revolutions.
        chosen = cfg.cache.setdefault("selected", {})
        factor = chosen.get(k)
        if factor is None:
            factor = chosen[k] = select(whole, k)
    return _response(model, solve_factored(factor, node_loads, frame="local"), terms_at(cfg.drive, k))


def _response(model: Discretization, sol, drive):
    """``(z, out, N)`` of a single-configuration solution: node displacements, outputs and the
    segment axial forces; ``drive``: the configuration's drive-torque terms
    (:meth:`FourBarMechanism.drive_torque_terms`)."""
    z = np.concatenate([sol.members[l.name].state[..., 0, :3].reshape(-1) for l in model.links])
    out = [np.reshape(torque_from_terms(sol.reactions, *drive), ())]
    for k, g in enumerate(model.gauges):
        b, a = gauge_strains(sol.members[g.link], g, axial_sampling=model.gauge_axial_sampling(k))
        out += [b.reshape(()), a.reshape(())]
    N = np.concatenate([segment_forces(sol.members[l.name]).reshape(-1) for l in model.links])
    return StepSolution(z, np.array(out), N)


def _node_loads(model: Discretization, loads):
    """The stacked local ``loads`` (n_dof) as the per-link node loads of a solve."""
    return {l.name: loads[model.offsets[l.name]:model.offsets[l.name] + 3 * l.n_nodes]
            .reshape(l.n_nodes, 3)[None, None] for l in model.links}


def kernel_data(model: Discretization, cfg):
    """The arrays of a configuration batch the compiled march reads (cached in the batch): its maps
    (``Zx, Ox, Ax, P0, rigid, omega``), or placeholder maps and its stored factorizations
    (:class:`tmm_core.configuration_batch.StepFactors`), as
    ``(Zx, Ox, Ax, P0, rigid, omega, on_factors)``: ``on_factors`` is None for maps
    (:func:`tmm_core.compiled.time_step.march_arrays`)."""
    data = cfg.cache.get("kernel")
    if data is None:
        maps, fac = cfg.maps, cfg.factors
        B = len(cfg)
        n, ns, no = model.n_dof, len(model.segments.length), model.outputs.size
        dynamic = model.axial_force == "dynamic"
        motion = cfg.motion
        omega = np.concatenate([np.repeat(np.asarray(motion.link(l.name).omega, float).reshape(B, 1), 3 * l.n_nodes,
                                          axis=1) for l in model.links], axis=1) if model.coupling.coriolis else \
            np.zeros((1, model.n_dof))
        # The augmented maps (StepMaps), or placeholders of the same array types.
        if maps is not None:
            arrays = (maps.Zx, maps.Ox, maps.Ax if dynamic else np.zeros((1, ns, n + 1)))
        else:
            arrays = (np.zeros((1, n, n + 1)), np.zeros((1, no, n + 1)), np.zeros((1, ns, n + 1)))
        data = tuple(np.ascontiguousarray(x, dtype=float) for x in arrays + (
            cfg.P0 if dynamic else np.zeros((1, ns)), cfg.rigid, omega))
        data += (compiled_time_step.march_arrays(fac, model.n_dof // 3, ns, no),)
        cfg.cache["kernel"] = data
    return data


