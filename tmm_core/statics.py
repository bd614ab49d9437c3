"""Static analysis of an instantaneous structure: linear, beam-column and large deflection.

Nonlinearity is handled, as in Shin (§6.1, ch. 4), by successive linear solutions: the axial
force of every segment (beam-column coupling) and, in large-deflection mode, the rotation of
every segment chord are taken from the previous iterate and the structure is solved again,
until both stop changing.

Large deflection is co-rotational: each segment is a small-deflection beam-column in its own
chord frame, rotated by the chord angle of the previous iterate, and forces are resolved in
that frame (see :func:`tmm_core.matrices.field_matrix`). As the segment count grows this
converges to the geometrically exact (elastica) solution; Shin's ch. 4 method is the same idea
with the chord angle approximated by half the segment slope.

Owns: static analysis of an instantaneous structure. Boundaries: no time domain.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .compiled import dense as compiled_dense
from .errors import ConvergenceError, InputError
from .post import distortion, static_safety_factor, surface_stresses
from .structure import LinearSolution, LoadCase, MemberResult, Structure, solve_linear


@dataclass(frozen=True)
class StaticSolution:
    """Result of :func:`solve_static`."""

    linear: LinearSolution
    mode: str                # 'linear' | 'beam_column' | 'large_deflection'
    iterations: int
    last_change: float       # relative change of the last iteration

    @property
    def members(self) -> Mapping[str, MemberResult]:
        return self.linear.members

    @property
    def reactions(self) -> Mapping[str, np.ndarray]:
        """``{joint: (..., 3)}`` force and moment applied by the ground [N, N, N m], CCW positive."""
        return self.linear.reactions

    def reaction_moment(self, joint: str) -> np.ndarray:
        """Moment applied by the ground to the structure at a clamped joint [N m], CCW positive.

        At the clamped crank pivot of a mechanism this is the required drive torque."""
        if joint not in self.reactions:
            raise InputError(f"joint '{joint}' is not supported; supported joints: {list(self.reactions)}")
        return self.reactions[joint][..., 2]

    def stresses(self, member: str):
        return surface_stresses(self.members[member])

    def distortion(self, member: str):
        return distortion(self.members[member])

    def safety_factor(self, member: str, yield_strength_Pa=None):
        return static_safety_factor(self.members[member], yield_strength_Pa)


def _update(linear: LinearSolution, large: bool):
    """Segment axial forces along the chord and chord rotations from a solution."""
    P, beta = {}, {}
    for name, r in linear.members.items():
        m = r.member
        L = np.asarray(m.segment_lengths)
        u, w = r.u, r.w
        if large:
            b = np.arctan2(w[..., 1:] - w[..., :-1], L + u[..., 1:] - u[..., :-1])
        else:
            b = np.zeros_like(L * u[..., 1:])
        # Axial force along the chord: mean of the segment's two end values.
        N0, V0 = r.N[..., :-1, 1], r.V[..., :-1, 1]
        N1, V1 = r.N[..., 1:, 0], r.V[..., 1:, 0]
        Nc = 0.5 * (np.cos(b) * (N0 + N1) + np.sin(b) * (V0 + V1))
        P[name] = np.where(m.is_rigid, 0.0, Nc)
        beta[name] = b
    return P, beta


def change_weights(longest_member_m: float) -> np.ndarray:
    """Weights of the station-state entries (u, w, theta, M, V, N) in the iteration's change:
    rotations x length and moments / length, so displacements compare in m and forces in N."""
    return np.array([1.0, 1.0, longest_member_m, 1.0 / longest_member_m, 1.0, 1.0])


def change_scales(states, weights) -> tuple:
    """``(largest |displacement|, largest |force|)`` of station-state arrays ``(..., 2, 6)``
    weighted by ``weights``: what the iteration's changes are relative to."""
    # The weights are positive: the largest weighted entry is the weight times the largest entry
    # of its column (the same floating-point value), one pass over each array instead of three.
    w = np.asarray(weights, dtype=float)
    largest = np.max([np.max(np.abs(np.reshape(x, (-1, 6))), axis=0, initial=0.0) for x in states], axis=0) * w
    return float(np.max(largest[:3])), float(np.max(largest[3:]))


def _change(new: LinearSolution, old: LinearSolution, weights, scales) -> np.ndarray:
    """Largest relative change between two iterates, per configuration of the batch: of the
    displacements against ``scales[0]``, of the forces against ``scales[1]``."""
    def worst(part):
        return np.max([np.max(np.abs(new.members[k].state[..., part] - old.members[k].state[..., part])
                              * weights[part], axis=(-3, -2, -1)) for k in new.members], axis=0)

    d, f = slice(0, 3), slice(3, 6)
    return np.maximum(worst(d) / scales[0] if scales[0] > 0 else 0.0, worst(f) / scales[1] if scales[1] > 0 else 0.0)


def iteration_converged(changes: list, tol: float) -> np.ndarray:
    """The stopping rule of the successive linear solutions (numpy and compiled), ``changes``
    the relative changes so far, each an array over the batch (one configuration each): where the
    last is below ``tol``, or the error of the last iterate that the changes imply is. The
    iteration contracts linearly (the beam-column update: ratios r ~ 1e-3 to 1e-2 on the rigs);
    with r the larger of the last two ratios of successive changes (taken only below 1/2, i.e.
    contracting), the last iterate lies within change * r / (1 - r) of the fixed point. This
    saves the solve whose only role was to show a change below ``tol``. (One ratio alone
    underestimated the error 2x on the FE rig at 241 rpm, where r grows from 2e-3 to 5e-3; the
    larger of two did not, on the four rigs of the benchmark.) The rule itself, for one
    configuration, is :func:`tmm_core.compiled.dense.iteration_converged`."""
    last = [np.asarray(c, dtype=float) for c in ([0.0, 0.0] + list(changes))[-3:]]
    c1, c2, c3 = np.broadcast_arrays(*last)
    out = np.zeros(c3.shape, dtype=bool)
    for i in np.ndindex(c3.shape):
        out[i] = compiled_dense.iteration_converged(c1[i], c2[i], c3[i], len(changes), tol)
    return out


def solve_static(structure: Structure, case: LoadCase, *, beam_column: bool = False,
                 large_deflection: bool = False, tol: float = 1e-10, max_iter: int = 200,
                 count_inertia: bool | None = None) -> StaticSolution:
    """Static solution of an instantaneous structure.

    ``beam_column``: iterate on segment axial forces (small deflection, Shin §3.3.1).
    ``large_deflection``: also iterate on segment chord rotations (implies beam-column).
    ``tol``: change of displacements and forces between iterations, relative to the largest
    displacement and force of the linear solution (the whole batch's), or the error it implies
    (:func:`iteration_converged`), that ends the iteration. Every configuration of a batch
    iterates to its own stop (the iteration count returned is the largest, the change the
    largest last change); a configuration stays at the axial forces it converged with. Raises
    :class:`ConvergenceError` after ``max_iter`` iterations, and
    :class:`tmm_core.errors.BucklingError` if in beam-column mode a member reaches its
    buckling load. ``count_inertia=True`` checks every solve for negative stiffness (the
    spin-softening check of the quasi-static analysis).
    """
    mode = "large_deflection" if large_deflection else ("beam_column" if beam_column else "linear")
    lin = solve_linear(structure, case, count_inertia=count_inertia)
    if mode == "linear":
        return StaticSolution(lin, mode, 1, 0.0)
    # Every configuration of a batch iterates to its own tolerance (its own changes, relaxation
    # and stop), as the compiled iteration does one configuration at a time: a configuration
    # that has converged keeps its axial forces, so the later solves repeat its solution.
    # Changes are relative to the largest displacement and force of the batch's linear solution.
    weights = change_weights(max(r.member.length for r in lin.members.values()))
    scales = change_scales([r.state for r in lin.members.values()], weights)
    batch = next(iter(lin.members.values())).state.shape[:-3]
    active = np.ones(batch, dtype=bool)
    relax, prev_change = np.ones(batch), np.full(batch, np.inf)
    iterations, last_change = np.full(batch, max_iter), np.zeros(batch)
    changes = []
    P, beta = _update(lin, large_deflection)
    for it in range(2, max_iter + 1):
        new = solve_linear(structure, case, P, beta, check_buckling=not large_deflection, count_inertia=count_inertia)
        change = np.where(active, _change(new, lin, weights, scales), 0.0)
        if not np.all(np.isfinite(change)):
            raise ConvergenceError(f"{mode} iteration produced non-finite values at iteration {it}")
        lin = new
        changes.append(change)
        done = active & iteration_converged(changes, tol)
        iterations[done], last_change[done] = it, change[done]
        active &= ~done
        if not active.any():
            return StaticSolution(lin, mode, int(np.max(iterations)), float(np.max(last_change)))
        relax[active & (change > prev_change) & (relax > 0.15)] *= 0.5  # damp an oscillating iteration
        prev_change = np.where(active, change, prev_change)
        P_new, beta_new = _update(lin, large_deflection)
        keep, step = ~active[..., None], relax[..., None]
        P = {k: np.where(keep, P[k], P[k] + step * (P_new[k] - P[k])) for k in P}
        beta = {k: np.where(keep, beta[k], beta[k] + step * (beta_new[k] - beta[k])) for k in beta}
    raise ConvergenceError(f"{mode} iteration did not converge in {max_iter} iterations "
                           f"(largest last relative change {float(np.max(changes[-1])):.3g}, tolerance {tol:.3g})")


def external_resultant(solution: StaticSolution | LinearSolution, deformed: bool = False) -> np.ndarray:
    """Sum of all external actions on the structure, ``(..., 3)``: (Fx, Fy) [N] and the moment
    about the global origin [N m]. Includes applied nodal and distributed loads, forces of
    springs to ground and support reactions; it is zero for an equilibrium solution.

    ``deformed``: take moment arms at the deformed positions (large-deflection equilibrium);
    otherwise at the undeformed positions (small-deflection theory).
    """
    lin = solution.linear if isinstance(solution, StaticSolution) else solution
    case = lin.case
    total = 0.0
    for name, r in lin.members.items():
        m = r.member
        X = r.node_positions + (r.displacement if deformed else 0.0)
        F = np.zeros(r.state.shape[:-2] + (3,))
        # Rotation local -> global of (x, y, theta) triples, for load cases given in local frames.
        R3 = np.zeros(r.angle.shape + (3, 3))
        R3[..., :2, :2] = r.rotation
        R3[..., 2, 2] = 1.0
        to_global = case.frame == "local"
        loads = case.node_loads.get(name)
        if loads is not None:
            loads = np.asarray(loads)
            F = F + (np.einsum("...ij,...nj->...ni", R3, loads) if to_global else loads)
        K = case.node_stiffness.get(name)
        if K is not None:
            if to_global:
                K = np.einsum("...ij,...njk,...lk->...nil", R3, K, R3)
            dg = np.concatenate([r.displacement, r.theta[..., None]], -1)
            F = F - np.einsum("...nij,...nj->...ni", K, dg)
        mom = F[..., 2] + X[..., 0] * F[..., 1] - X[..., 1] * F[..., 0]
        total = total + np.stack([F[..., 0].sum(-1), F[..., 1].sum(-1), mom.sum(-1)], -1)
        q = case.distributed_loads.get(name)
        if q is not None:
            Lseg = np.asarray(m.segment_lengths)[:, None]
            mid = 0.5 * (X[..., 1:, :] + X[..., :-1, :])
            R = np.broadcast_to(q * Lseg, np.broadcast_shapes(np.shape(q), mid.shape))
            mq = mid[..., 0] * R[..., 1] - mid[..., 1] * R[..., 0]
            total = total + np.stack([R[..., 0].sum(-1), R[..., 1].sum(-1), mq.sum(-1)], -1)
    for jname, R in lin.reactions.items():
        Xj = np.asarray(case.joint_positions[jname], dtype=float)
        if deformed:
            Xj = Xj + lin.joint_displacement[jname]
        total = total + np.stack([R[..., 0], R[..., 1], R[..., 2] + Xj[..., 0] * R[..., 1] - Xj[..., 1] * R[..., 0]], -1)
    return total
