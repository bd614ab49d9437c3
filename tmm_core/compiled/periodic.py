"""Compiled linearized revolutions of the periodic solver (numba): the monodromy matrix of the
time-discrete step and the linear model's shooting pass.

:mod:`tmm_core.periodic` marches every unit state (n_state = len(keys) * n_dof columns) through
one revolution of the time step, linearized about a trajectory (second-order step) or as it is
(linear step); its numpy code (``_monodromy``, ``_batched_step``) is the reference, and
``tests/test_periodic.py`` checks this module against it. The same arithmetic is arranged so
that the per-column work is one dense product per step:

* the step's loads are linear in the integrator history ``(h_a, h_v)`` (inertia, Coriolis and
  Kelvin-Voigt history; the second-order pseudo-loads' velocity part) and are formed per column
  in O(n_dof) with the sparse structure of those terms;
* the second-order step's Jacobian ``J`` in (displacements, segment axial forces) is built from
  the sparse pseudo-load derivatives (4x4 blocks per segment) and solved once per step for the
  load-to-displacement operator ``W = (J^-1 [[Z, 0], [A, I]])[:n_dof]`` (n_dof + n_seg right-hand
  sides instead of n_state), then every column's displacements are ``W @ [loads; axial part]``;
* the axial-force unknowns and equations of ``J`` are scaled by EA/L (condition ~1e13 -> ~1e5);
* the integrator's history and update are linear in its state with scalar coefficients per
  state array, read off the integrator itself (:mod:`tmm_core.compiled.integrators`, which the
  march steps through too), so no integrator formula is repeated here; nor are the step's
  history loads (:func:`tmm_core.compiled.time_step.history_loads`, the march's too);
* state arrays the first step does not see (generalized-alpha: 1 of 4, Newmark: 1 of 3) are not
  marched: their columns of Phi are combinations of the others
  (:func:`dependent_keys`).

Why: the numpy monodromy spent about 1.4 ms per step in Python calls and small dense solves with
n_state right-hand sides (measured 0.7-1 s per revolution of 720 steps on the FE rig, 54 dof,
216 states; one to three per periodic solve). Here (same rig, one thread, warm): 0.05 s for the
linear pass, 0.14 s per monodromy, of which about half is the per-step solve for W.

Kernels are compiled on first use (:func:`tmm_core.compiled.binding.linearized`) and cached on
disk (numba ``cache=True``, in the compiled layer's keyed folder: an edit of any kernel file starts
a fresh cache, :mod:`tmm_core.compiled.cache`). The Python drivers below (the shooting pass, the
monodromy, the trajectory's velocities) take the compiled ``kernels`` from their caller
(:func:`tmm_core.compiled.binding.linearized`), since the binding imports this module.

Owns: the compiled linearized revolutions (:func:`push`, :func:`velocities`) and their drivers. Boundaries: the numpy path in tmm_core.periodic is
the reference; the step's maps and data come from :func:`tmm_core.time_step.kernel_data`.
"""
from __future__ import annotations

import numpy as np

from ..integrators import linear_maps
from .integrators import advance, history
from .time_step import corotational_tangent, history_loads


def push(S, coef, idx, forced, maps, model, flags, c_v, trajectory):
    """March the states ``S`` (K slots, n_dof rows of M columns, each slot flattened: value
    ``(i, r)`` at ``i M + r``; a C-ordered ``(K, n_dof, M)`` array reshaped) in place through the steps at
    configurations ``idx`` of a map batch (augmented maps ``Zx``, ``Ax``:
    :class:`tmm_core.configuration_batch.StepMaps`): the linear step (``dynamic`` False: loads
    through the displacement map) or the second-order step linearized about the trajectory ``zs, vs,
    Ps`` (displacements [m, rad], velocities and segment axial forces [N] per step). The first
    ``forced`` columns also get the configuration's rigid-body loads and the maps' constant parts
    (the affine response of the linear step); the others are homogeneous (unit states).

    Columns are the last axis: every operation on a degree of freedom is a contiguous row
    operation over the M columns, and the displacements are one matrix product per step.

    Records (tuples, unpacked below): ``coef = (Hc, Gc, ez)`` (:func:`tmm_core.compiled.integrators.linear_maps`);
    ``maps = (Zx, Ax, P0, rigid, omega)``; ``model`` the march's model record
    (:meth:`tmm_core.discretization.Discretization.kernel_model`); ``flags = (coriolis, has_kv,
    dynamic, corotational)`` (``corotational``: the co-rotational segments' pseudo-loads, linearized
    by :func:`corotational_blocks`); ``trajectory = (zs, vs, Ps)``."""
    Hc, Gc, ez = coef
    Zx, Ax, P0, rigid, omega = maps
    # The mass damping blocks serve only the history loads (the whole record).
    m, _aM, _beta_node, seg_start, seg_end, seg_L, seg_EA, seg_beta, seg_K, _gauge_reading = model
    coriolis, has_kv, dynamic, corotational = flags
    zs, vs, Ps = trajectory
    K, nM = S.shape
    n = m.shape[0]
    M = nM // n
    ns = seg_L.shape[0]
    nx = n + ns
    # Flat rows of M values (value (i, r) at i M + r), as the integrator and the history loads
    # take them; L is the loads' matrix for the products.
    h_a = np.empty(nM)
    h_v = np.empty(nM)
    loads = np.empty(nM)
    zf = np.empty(nM)
    L = np.zeros((n + 1, M))         # row n stays zero: Zx[k] @ L leaves out the constant column
    D = np.empty((ns, M))
    q_ = np.empty(M)
    Snew = np.empty((K, nM))
    EAL = seg_EA / seg_L
    kb = seg_beta * EAL
    # Per-segment data of the linearization: the node-vector index of (w0, theta0, w1, theta1),
    # the consistent geometric-stiffness matrix G (second_order.geometric_matrices), G d, G v_d.
    dof = np.empty((ns, 4), dtype=np.int64)
    G = np.empty((ns, 4, 4))
    base = np.array([[36.0, 3.0, -36.0, 3.0], [3.0, 4.0, -3.0, -1.0], [-36.0, -3.0, 36.0, -3.0], [3.0, -1.0, -3.0, 4.0]])
    power = np.array([[0, 1, 0, 1], [1, 2, 1, 2], [0, 1, 0, 1], [1, 2, 1, 2]])
    for s in range(ns):
        dof[s, 0], dof[s, 1], dof[s, 2], dof[s, 3] = seg_start[s] + 1, seg_start[s] + 2, seg_end[s] + 1, seg_end[s] + 2
        for p in range(4):
            for q in range(4):
                G[s, p, q] = base[p, q] * seg_L[s] ** power[p, q] / (30.0 * seg_L[s])
    ga = np.empty((ns, 4))
    Fz = np.empty((ns, 4))           # dF/dz of the shortening force at the segment's 4 dofs
    J = np.empty((nx, nx))
    B = np.zeros((nx, nx))           # [[Z, 0], [A, I]], rows scaled like J's
    W1 = np.zeros((n, n + 1))        # the load block of W (and a zero column, as L's zero row)
    W2 = np.empty((n, ns))           # the axial-force block of W
    # The co-rotational segments' derivatives on their six dofs (corotational_blocks).
    blocks = (np.empty((ns, 6, 6)), np.empty((ns, 6, 6)), np.empty((ns, 6)), np.empty((ns, 6)), np.empty((ns, 6)))
    local = np.empty((2, 6))
    for j in range(idx.shape[0]):
        k = idx[j]
        history(Hc, S, h_a, h_v)
        history_loads(k, h_a, h_v, model, omega, (coriolis, has_kv), loads)
        for i in range(n):
            for r in range(M):
                L[i, r] = loads[i * M + r]
        if dynamic and corotational:
            corotational_blocks(j, k, (seg_start, seg_L, seg_EA, seg_beta, seg_K), trajectory, P0, blocks, local)
            z = corotational_response(j, k, (nx, n, ns, M, c_v), (seg_start, EAL, kb), (Zx, Ax), blocks, h_v,
                                      (L, D, J, B, W1, W2))
        elif dynamic:
            for s in range(ns):
                for p in range(4):
                    sa = 0.0
                    sb = 0.0
                    for q in range(4):
                        sa += G[s, p, q] * zs[j, dof[s, q]]
                        sb += G[s, p, q] * vs[j, dof[s, q]]
                    ga[s, p] = sa
                    # F = EA/L (Delta + beta Delta_dot) with v = c_v z + h_v.
                    Fz[s, p] = EAL[s] * (sa + seg_beta[s] * sb) + c_v * kb[s] * sa
            # Velocity-history part of the pseudo-loads and of the axial forces (damping and
            # shortening rate): f_h h_v on the axial dofs, (damping + F_h) h_v per segment.
            for s in range(ns):
                st, en = seg_start[s], seg_end[s]
                for r in range(M):
                    q_[r] = kb[s] * (ga[s, 0] * h_v[dof[s, 0] * M + r] + ga[s, 1] * h_v[dof[s, 1] * M + r]
                                     + ga[s, 2] * h_v[dof[s, 2] * M + r] + ga[s, 3] * h_v[dof[s, 3] * M + r])
                for r in range(M):
                    L[st, r] += q_[r]
                    L[en, r] -= q_[r]
                    D[s, r] = kb[s] * (h_v[en * M + r] - h_v[st * M + r]) + q_[r]
            # J = [[I - Z f_z, -Z f_P], [-(A f_z + F_z), I - A f_P]] with f_z = Su F_z - sum dP G
            # (segment blocks), f_P[dof_s, s] = -G d_s; rows of Z and A alike. The axial-force
            # unknowns and equations are scaled by EA/L (to displacements): unscaled, J mixes
            # metres and newtons and its condition number is ~1e13 (FE rig), scaled ~1e5.
            J[:, :] = 0.0
            for i in range(nx):
                row, rs = jacobian_row(i, k, n, (Zx, Ax), EAL)
                for s in range(ns):
                    t = row[seg_start[s]] - row[seg_end[s]]
                    dP = Ps[j, s] - P0[k, s]
                    fp = 0.0
                    for p in range(4):
                        fp -= row[dof[s, p]] * ga[s, p]
                    J[i, n + s] -= rs * fp * EAL[s]
                    for q in range(4):
                        g = 0.0
                        for p in range(4):
                            g += row[dof[s, p]] * G[s, p, q]
                        J[i, dof[s, q]] -= rs * (t * Fz[s, q] - dP * g)
                close_row(i, n, row, rs, (J, B))
            for s in range(ns):
                for q in range(4):
                    J[n + s, dof[s, q]] -= Fz[s, q] / EAL[s]
            z = solved_response((J, B, W1, W2), L, D)
        else:
            z = np.dot(Zx[k], L)
            for i in range(n):
                acc = Zx[k, i, n]
                for q in range(n):
                    acc += Zx[k, i, q] * rigid[k, q]
                for r in range(forced):
                    z[i, r] += acc
        for i in range(n):
            for r in range(M):
                zf[i * M + r] = z[i, r]
        advance(Gc, ez, S, zf, Snew)


def jacobian_row(i, k, n, maps, EAL):
    """Row ``i`` of the step's Jacobian in (displacements, axial forces scaled by EA/L): the
    displacement map's row ``Zx[k, i]`` (i < n) or the axial-force map's ``Ax[k, i - n]`` and its
    scale ``1`` or ``L/EA``. Record: ``maps = (Zx, Ax)``."""
    Zx, Ax = maps
    if i < n:
        return Zx[k, i], 1.0
    return Ax[k, i - n], 1.0 / EAL[i - n]


def close_row(i, n, row, rs, system):
    """Row ``i`` of ``J`` gets its identity and row ``i`` of ``B = [[Z, 0], [A, I]]`` its map row,
    both scaled by ``rs``. Record: ``system = (J, B)``."""
    J, B = system
    J[i, i] += 1.0
    for q in range(n):
        B[i, q] = rs * row[q]
    if i >= n:
        B[i, i] = rs


def solved_response(system, L, D):
    """The step's displacements (n_dof, M): ``W = J^-1 B`` split into its load block ``W1`` and its
    axial-force block ``W2``, applied to the loads ``L`` and the axial-force parts ``D``. Record:
    ``system = (J, B, W1, W2)`` (``W1`` keeps a zero last column, as ``L`` a zero last row)."""
    J, B, W1, W2 = system
    n, ns = W2.shape
    W = np.linalg.solve(J, B)
    for i in range(n):
        for q in range(n):
            W1[i, q] = W[i, q]
        for s in range(ns):
            W2[i, s] = W[i, n + s]
    return np.dot(W1, L) + np.dot(W2, D)


def corotational_blocks(j, k, segments, trajectory, P0, blocks, local):
    """The co-rotational segments' derivatives at step ``j`` (configuration ``k``) of the
    trajectory, exact (:func:`tmm_core.compiled.time_step.corotational_tangent`;
    :func:`tmm_core.second_order.corotational_linearization` is the reference, step for step):
    into ``blocks = (f_d, f_v, F_d, F_v, f_P)``, the pseudo-loads on the segment's six dofs by its
    displacements and its velocities (n_seg, 6, 6), its shortening force by them (n_seg, 6) and
    the pseudo-loads by its axial force (n_seg, 6). Records: ``segments = (start, L, EA, beta,
    K)``, ``trajectory = (zs, vs, Ps)``; ``local`` (2, 6): work."""
    seg_start, seg_L, seg_EA, seg_beta, seg_K = segments
    zs, vs, Ps = trajectory
    f_d, f_v, F_d, F_v, f_P = blocks
    for s in range(seg_start.shape[0]):
        i0 = seg_start[s]
        section = (seg_L[s], seg_EA[s], seg_beta[s], seg_K[s, 2, 2], seg_K[s, 2, 5], seg_K[s, 5, 5])
        for q in range(6):
            local[0, q] = zs[j, i0 + q]
            local[1, q] = vs[j, i0 + q]
        corotational_tangent(section, local[0], local[1], Ps[j, s], False, P0[k, s], f_d[s], f_v[s], f_P[s], F_d[s],
                             F_v[s])


def corotational_response(j, k, sizes, segments, maps, blocks, h_v, work):
    """The step's displacements (n_dof, M) of :func:`push` with the co-rotational segments'
    derivatives ``blocks`` (:func:`corotational_blocks`), as its second-order branch builds them
    from the 4 x 4 blocks: the velocity-history part of the loads ``L`` and axial forces ``D``,
    the step's Jacobian ``J`` in (displacements, axial forces scaled by EA/L) and ``W``. Records:
    ``sizes = (nx, n, ns, M, c_v)``, ``segments = (start, EA/L, beta EA/L)``, ``maps = (Zx,
    Ax)``, ``work = (L, D, J, B, W1, W2)`` (``L`` holds the step's history loads on entry)."""
    nx, n, ns, M, c_v = sizes
    seg_start, EAL, kb = segments
    Zx, Ax = maps
    f_d, f_v, F_d, F_v, f_P = blocks
    L, D, J, B, W1, W2 = work
    for s in range(ns):
        i0 = seg_start[s]
        for r in range(M):
            acc_F = 0.0
            for q in range(6):
                acc_F += F_v[s, q] * h_v[(i0 + q) * M + r]
            D[s, r] = kb[s] * (h_v[(i0 + 3) * M + r] - h_v[i0 * M + r]) + acc_F
            for p in range(6):
                acc = 0.0
                for q in range(6):
                    acc += f_v[s, p, q] * h_v[(i0 + q) * M + r]
                L[i0 + p, r] += acc
    J[:, :] = 0.0
    for i in range(nx):
        row, rs = jacobian_row(i, k, n, (Zx, Ax), EAL)
        for s in range(ns):
            i0 = seg_start[s]
            fp = 0.0
            for p in range(6):
                fp += row[i0 + p] * f_P[s, p]
            J[i, n + s] -= rs * fp * EAL[s]
            for q in range(6):
                g = 0.0
                for p in range(6):
                    g += row[i0 + p] * (f_d[s, p, q] + c_v * f_v[s, p, q])
                J[i, i0 + q] -= rs * g
        close_row(i, n, row, rs, (J, B))
    for s in range(ns):
        for q in range(6):
            J[n + s, seg_start[s] + q] -= (F_d[s, q] + c_v * F_v[s, q]) / EAL[s]
    return solved_response((J, B, W1, W2), L, D)


def velocities(S, coef, c_v, zs, vs):
    """Velocities ``vs[j] = c_v zs[j] + h_v`` along the displacements ``zs`` (N, n_dof) of a march
    from the states ``S`` (K slots, n_dof; updated in place to the end); ``coef = (Hc, Gc, ez)``."""
    Hc, Gc, ez = coef
    K, n = S.shape
    Snew = np.empty((K, n))
    h_a = np.empty(n)
    h_v = np.empty(n)
    for j in range(zs.shape[0]):
        history(Hc, S, h_a, h_v)
        for i in range(n):
            vs[j, i] = c_v * zs[j, i] + h_v[i]
        advance(Gc, ez, S, zs[j], Snew)


def trajectory_velocities(kernels, integrator, state, zs, dt: float) -> np.ndarray:
    """Velocities after every step of a march with displacements ``zs`` (N, n_dof) from the
    integrator ``state`` (a dict as :meth:`integrator.initial` gives), step ``dt`` [s]: the
    ``v = c_v z + h_v`` of :func:`tmm_core.periodic._revolution`'s Python loop."""
    slots, Hc, Gc, ez = linear_maps(integrator, dt)
    _, c_v = integrator.coefficients(dt)
    zs = np.ascontiguousarray(zs, dtype=float)
    S = np.array([np.asarray(state[s], dtype=float) for s in slots])
    vs = np.empty_like(zs)
    kernels.velocities(S, (Hc, Gc, ez), c_v, zs, vs)
    return vs


def _inputs(model, data, dt):
    """What :func:`push` reads, from the batch's compiled-march arrays ``data``
    (:func:`tmm_core.time_step.kernel_data` of a batch with its maps) and the ``model``
    (:class:`tmm_core.discretization.Discretization`): ``(slots, coef, maps, kernel,
    (coriolis, has_kv), c_v)``."""
    Zx, _, Ax, P0, rigid, omega = data[:6]
    slots, Hc, Gc, ez = linear_maps(model.integrator, dt)
    _, c_v = model.integrator.coefficients(dt)
    return slots, (Hc, Gc, ez), (Zx, Ax, P0, rigid, omega), model.kernel_model(), (model.coupling.coriolis,
                                                                                   model.has_kv), c_v


def dependent_keys(slots, keys, Hc, Gc):
    """``(marched, dependent, C)``: positions in ``keys`` of the state arrays whose unit states are
    marched, of the others, and ``C`` (len(marched), len(dependent)) with
    ``Phi e_dependent[t] = sum_p C[p, t] Phi e_marched[p]`` per degree of freedom.

    Why: the first step acts on the state only through the integrator update ``Gc x`` and the
    history ``Hc x``, which span 3 of the 4 generalized-alpha arrays (2 of 3 for Newmark): a
    state n0 with ``Gc n0 = Hc n0 = 0`` is annihilated, so each dependent unit state is a
    combination of the marched ones, and a quarter (a third) of the linearized work is saved.
    n0 comes from an SVD with the columns scaled to unit size (the coefficients span powers of
    1/dt); the dependent arrays are those with the largest components of n0 (pivoted QR)."""
    import scipy.linalg
    cols = [slots.index(key) for key in keys]
    M = np.vstack([Gc[:, cols], Hc[:, cols]])
    scale = np.max(np.abs(M), axis=0)
    scale[scale == 0.0] = 1.0
    _, sv, Vt = np.linalg.svd(M / scale)                 # M = (M / scale) diag(scale)
    r = int(np.sum(sv > 1e-12 * sv[0]))
    if r == len(keys):
        return list(range(len(keys))), [], np.zeros((len(keys), 0))
    null_scaled = Vt[r:]                                  # (q, nk): null space in scaled coordinates
    _, _, piv = scipy.linalg.qr(null_scaled, pivoting=True)
    dependent = sorted(int(j) for j in piv[:len(null_scaled)])
    marched = [j for j in range(len(keys)) if j not in dependent]
    null = (null_scaled / scale).T                        # (nk, q), M null = 0
    # e_j - null inv(null[dependent]) e_j vanishes at the dependent arrays and has the same image.
    C = -(null @ np.linalg.inv(null[dependent]))[marched]
    return marched, dependent, C


def _initial_states(slots, keys, n, marched, extra=0):
    """States ``(K, n, extra + len(marched) n)``: ``extra`` zero columns, then a unit state per
    degree of freedom of each marched array of ``keys``."""
    S = np.zeros((len(slots), n, extra + len(marched) * n))
    i = np.arange(n)
    for p, j in enumerate(marched):
        S[slots.index(keys[j]), i, extra + p * n + i] = 1.0
    return S


def _stacked(S, slots, keys):
    """The stacked state vectors of states ``S`` as columns ``(len(keys) * n, M)``."""
    return np.concatenate([S[slots.index(key)] for key in keys], axis=0)


def _expand(X, marched, dependent, C, n):
    """The full ``Phi`` (columns: unit states of every array) from the marched columns ``X``."""
    Phi = np.empty((X.shape[0], (len(marched) + len(dependent)) * n))
    for p, j in enumerate(marched):
        Phi[:, j * n:(j + 1) * n] = X[:, p * n:(p + 1) * n]
    for t, j in enumerate(dependent):
        Phi[:, j * n:(j + 1) * n] = sum(C[p, t] * X[:, p * n:(p + 1) * n] for p in range(len(marched)))
    return Phi


def linear_shooting(kernels, model, data, keys, N: int, dt: float):
    """The linear step's revolution ``x_N = Phi x_0 + c`` (as the first pass of
    :func:`tmm_core.periodic.periodic_steady_state`): ``(Phi, c)`` for the stacked state of
    ``keys``, ``data`` being the compiled-march arrays of the N configurations of the revolution
    (:func:`tmm_core.time_step.kernel_data`, with the maps)."""
    slots, coef, maps, kernel, flags, c_v = _inputs(model, data, dt)
    n = model.n_dof
    marched, dependent, C = dependent_keys(slots, keys, coef[0], coef[1])
    S = _initial_states(slots, keys, n, marched, extra=1)
    no_trajectory = (np.zeros((0, n)), np.zeros((0, n)), np.zeros((0, len(model.segments.length))))
    kernels.push(S.reshape(len(S), -1), coef, np.arange(1, N + 1) % N, 1, maps, kernel, (*flags, False, False), c_v,
                 no_trajectory)
    X = _stacked(S, slots, keys)
    return _expand(X[:, 1:], marched, dependent, C, n), X[:, 0].copy()


def monodromy(kernels, model, data, keys, trajectory, dt: float) -> np.ndarray:
    """Monodromy matrix of the second-order step linearized about ``trajectory`` (a list of
    ``(idx, z, v, P)`` per step, as :func:`tmm_core.periodic._revolution` returns it); ``data`` as
    :func:`linear_shooting`."""
    slots, coef, maps, kernel, flags, c_v = _inputs(model, data, dt)
    idx = np.array([t[0] for t in trajectory], dtype=np.int64)
    linearized_about = tuple(np.ascontiguousarray(np.array([t[i] for t in trajectory]), dtype=float) for i in (1, 2, 3))
    marched, dependent, C = dependent_keys(slots, keys, coef[0], coef[1])
    S = _initial_states(slots, keys, model.n_dof, marched)
    kernels.push(S.reshape(len(S), -1), coef, idx, 0, maps, kernel,
                 (*flags, True, model.strain_measure == "corotational"), c_v, linearized_about)
    return _expand(_stacked(S, slots, keys), marched, dependent, C, model.n_dof)
