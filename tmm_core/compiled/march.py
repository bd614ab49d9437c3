"""Compiled march of the time-domain step on precomputed load-to-response maps (numba).

The numpy step (:mod:`tmm_core.time_step`: ``step_loads``, ``solve_step``; the integrators) is
the reference; this module does the same arithmetic in one compiled loop over the steps of a
march, for configurations whose dense maps are cached (a constant-speed revolution): the step's
loads (D'Alembert of the configuration, inertia and Kelvin-Voigt history, Coriolis terms), the
second-order pseudo-load iteration with Anderson mixing (:mod:`tmm_core.second_order`), the
outputs and the integrator update. A test checks it against the numpy path to 1e-12 over a
revolution.

Why compiled: the arithmetic of a step is a few tens of kflop, but the numpy path spends about
a millisecond per step in Python calls (measured: 1.8 ms per step on the FE rig at 8 segments).

A step the kernel cannot finish (its iteration does not converge, or its configuration's
estimated axial forces leave the dynamic system indefinite) is handed back: the march stops
before it and returns its index, and the caller solves that step with the numpy path (which
refactorizes at the step's own axial forces) and resumes.

The integrator (:mod:`tmm_core.compiled.integrators`, any integrator of
:mod:`tmm_core.integrators` as its linear maps) and the step's history loads
(:func:`tmm_core.compiled.time_step.history_loads`) are the parts the periodic solver's
linearized revolutions share.

Kernels are compiled on first use by :mod:`tmm_core.compiled.binding` and cached on disk.

Owns: the compiled march. Boundaries: the numpy path (tmm_core.time_step) stays the reference.
"""
from __future__ import annotations

import numpy as np

# The compiled ones once bound (tmm_core.compiled.binding): the step's parts the periodic
# solver's linearized revolutions share, and the solve on stored factorizations.
from .integrators import advance, history
from .time_step import chord_lag, corotational_segment, factored_solve, history_loads

# numba is imported (and the kernels compiled or loaded from its cache) on first use only, by
# tmm_core.compiled.binding: the command line and the numpy path do not pay for it. Without numba
# the numpy path still works.

def shape_products(start, end, L, z, delta, G):
    """Shortening 1/2 d^T G d and the four components of G d per segment (second_order.py)."""
    for s in range(L.shape[0]):
        i0, i1, l = start[s], end[s], L[s]
        w0, t0, w1, t1 = z[i0 + 1], z[i0 + 2], z[i1 + 1], z[i1 + 2]
        dw = w0 - w1
        g0 = (36.0 * dw + 3.0 * l * (t0 + t1)) / (30.0 * l)
        g1 = (3.0 * dw + l * (4.0 * t0 - t1)) / 30.0
        g3 = (3.0 * dw + l * (4.0 * t1 - t0)) / 30.0
        G[s, 0], G[s, 1], G[s, 2], G[s, 3] = g0, g1, -g0, g3
        delta[s] = 0.5 * (dw * g0 + t0 * g1 + t1 * g3)


def corotational_loads(which, segments, z, h_v, c_v, P, P0, f, local, F, excess):
    """The co-rotational segments ``which`` (:func:`tmm_core.compiled.time_step.corotational_segment`):
    adds their pseudo-loads at displacements ``z`` (velocities ``c_v z + h_v``) and axial forces
    ``P`` [N] into ``f`` and writes their shortening forces ``F`` [N] and ``excess = L (e - a)``
    [m] (indexed by segment). ``P0``: the factorization's axial forces [N]. Record: ``segments =
    (start, end, L, EA, beta, K)`` (the bending stiffness from the segment block ``K[s]``);
    ``local`` (2, 6): work. One call for all the segments: a call per segment, passing the record
    of arrays each time, cost the march 7 us a step on the FE rig (twice the step)."""
    start, _end, length, EA, beta, K = segments
    for s in which:
        i0 = start[s]
        for q in range(6):
            local[0, q] = z[i0 + q]
            local[1, q] = c_v * z[i0 + q] + h_v[i0 + q]
        out = corotational_segment((length[s], EA[s], beta[s], K[s, 2, 2], K[s, 2, 5], K[s, 5, 5]), local[0],
                                   local[1], P[s], P0[s])
        for q in range(6):
            f[i0 + q] += out[q]
        F[s], excess[s] = out[6], out[7]


def affine(Mx, k, v, out):
    """``out = Mx[k, :, :n] @ v + Mx[k, :, n]`` (``n = len(v)``): one augmented affine map of the
    batch (:class:`tmm_core.configuration_batch.StepMaps`) at configuration ``k``."""
    n = v.shape[0]
    for i in range(out.shape[0]):
        s_ = Mx[k, i, n]
        for q in range(n):
            s_ += Mx[k, i, q] * v[q]
        out[i] = s_


def anderson_coefficients(dR, h, r, gamma, Q, R):
    """Least-squares coefficients ``gamma[:h]`` of ``dR[:h].T gamma = r`` by modified
    Gram-Schmidt QR (h <= 4 columns; ``dR`` and ``Q`` hold a history column per row, so that the
    inner loops run over contiguous memory). A column whose remaining norm is below 1e-12 of the
    largest column's (a rank-deficient history) gets a zero coefficient. The numpy path uses the
    same arithmetic (:func:`tmm_core.anderson.anderson_coefficients`): a LAPACK least-squares
    call cost more than the rest of a step here."""
    nx = dR.shape[1]
    big = 0.0
    for c in range(h):
        norm = 0.0
        for i in range(nx):
            Q[c, i] = dR[c, i]
            norm += dR[c, i] * dR[c, i]
        big = max(big, np.sqrt(norm))
    for c in range(h):
        for p in range(c):
            dot = 0.0
            for i in range(nx):
                dot += Q[p, i] * Q[c, i]
            R[p, c] = dot
            for i in range(nx):
                Q[c, i] -= dot * Q[p, i]
        norm = 0.0
        for i in range(nx):
            norm += Q[c, i] * Q[c, i]
        norm = np.sqrt(norm)
        R[c, c] = norm
        if norm > 1e-12 * big:
            for i in range(nx):
                Q[c, i] /= norm
        else:
            for i in range(nx):
                Q[c, i] = 0.0
    for c in range(h - 1, -1, -1):
        if R[c, c] <= 1e-12 * big:
            gamma[c] = 0.0
            continue
        acc = 0.0
        for i in range(nx):
            acc += Q[c, i] * r[i]
        for p in range(c + 1, h):
            acc -= R[c, p] * gamma[p]
        gamma[c] = acc / R[c, c]


def march(integrator, idx, maps, on_factors, model, settings, state, recorded):
    """March the steps whose configuration indices are ``idx`` (into the map batch), updating
    the integrator states ``S`` and the segment axial forces ``P`` in place and writing
    the outputs of each step into ``out_hist`` / ``z_hist`` / ``P_hist`` (rows; an array with no
    rows is not written) and its iteration count. The responses come from the augmented maps
    ``Zx, Ox, Ax`` (:class:`tmm_core.configuration_batch.StepMaps`) or, with ``on_factors`` given, from
    solves on the stored factorizations (:func:`tmm_core.compiled.time_step.factored_solve`:
    ``flayout, fstored, fwork``; the outputs ``Ocx`` applied to ``y``).
    Returns the number of steps done (``len(idx)`` unless a step failed: then the state is that
    of the step before it).

    Records (tuples, unpacked below): ``integrator = (Hc, Gc, ez, dva, dt [s], c_v)``, the
    integrator's linear maps (:func:`tmm_core.compiled.integrators.linear_maps`), the positions
    of the displacement, velocity and acceleration among its state arrays, the step and the
    velocity coefficient; ``maps = (Zx, Ox, Ax, P0, rigid, omega)`` and ``on_factors = (flayout,
    fstored, fwork, Ocx)`` or None for a batch with maps, the configuration batch's data
    (:func:`tmm_core.time_step.kernel_data`); ``model = (m, aM, beta_node, seg_start,
    seg_end, seg_L, seg_EA, seg_beta, seg_K, (gauge_seg, gauge_w, bend_seg, bend_w))``, the last the
    two segments of each gauge's axial strain and the weights [1/m] of their shortenings, and the
    segment whose chord lag [rad] moves its co-rotational bending with the weight [-]
    (:meth:`tmm_core.discretization.Discretization.gauge_reading`); ``settings = (coriolis, has_kv,
    dynamic, shortening, own_force, corotational, tol_z, tol_P, max_iterations, depth)``
    (``corotational``: the co-rotational segments' pseudo-loads, :func:`corotational_loads`,
    instead of the second-order ones); ``state = (S, P)``
    with ``S (K, n_dof)`` the integrator's state arrays, updated in place; ``recorded =
    (out_hist, z_hist, P_hist, iterations)``."""
    Hc, Gc, ez, dva, dt, c_v = integrator
    Zx, Ox, Ax, P0, rigid, omega = maps
    # The masses, mass damping and bending blocks serve only the history loads (the whole record).
    _m, _aM, _beta_node, seg_start, seg_end, seg_L, seg_EA, seg_beta, seg_K, gauge_reading = model
    gauge_seg, gauge_w, bend_seg, bend_w = gauge_reading
    coriolis, has_kv, dynamic, shortening, own_force, corotational, tol_z, tol_P, max_iterations, depth = settings
    segments = (seg_start, seg_end, seg_L, seg_EA, seg_beta, seg_K)
    S, P = state
    out_hist, z_hist, P_hist, iterations = recorded

    K, n = S.shape
    ns = seg_L.shape[0]
    no = Ox.shape[1]
    nx = n + ns
    h_a = np.empty(n)
    h_v = np.empty(n)
    loads = np.empty(n)
    Snew = np.empty((K, n))
    zn = np.empty(n)
    d, v, a = S[dva[0]], S[dva[1]], S[dva[2]]
    f = np.empty(n)
    zt = np.empty(n)
    Pn = np.empty(ns)
    N = np.empty(ns)
    F = np.empty(ns)
    delta = np.empty(ns)
    G = np.empty((ns, 4))
    scratch = np.empty(n)           # the co-rotational loads at convergence (only their excess is kept)
    Pit = np.empty(ns)              # an iterate's axial forces
    every_segment = np.arange(ns)
    gauge_flat = gauge_seg.ravel().copy()
    local = np.empty((2, 6))        # a co-rotational segment's displacements and velocities
    damp = np.empty(ns)
    outv = np.empty(no)
    # Stored factorizations, or None (maps): numba prunes every ``on_factors is not None`` branch
    # of a march compiled for maps, so that it does not compile the factored solve in.
    if on_factors is not None:
        flayout, fstored, fwork, Ocx = on_factors
        y = np.empty(Ocx.shape[2] - 1)
    x = np.empty(nx)
    gx = np.empty(nx)
    r = np.empty(nx)
    prev_r = np.empty(nx)
    prev_g = np.empty(nx)
    dR = np.zeros((depth, nx))       # history columns as rows: contiguous inner loops
    dG = np.zeros((depth, nx))
    Q = np.empty((depth, nx))
    mix = np.empty(nx)
    R = np.empty((depth, depth))
    gamma = np.empty(depth)
    to_len = seg_L / seg_EA
    EAL = seg_EA / seg_L
    scale_P = 1e-9 * np.max(seg_EA)
    for j in range(idx.shape[0]):
        k = idx[j]
        history(Hc, S, h_a, h_v)
        # Loads: the configuration's D'Alembert loads and those of the integrator history.
        history_loads(k, h_a, h_v, model, omega, (coriolis, has_kv), loads)
        for i in range(n):
            loads[i] += rigid[k, i]
        if not dynamic:
            # (The factored solve is called only in its branch: passing its tuples of arrays to a
            # helper on every iteration cost the maps' march ~2 us a step.)
            if on_factors is not None:
                factored_solve(k, loads, flayout, fstored, fwork, zn, N, y)
                affine(Ocx, k, y, outv)
            else:
                affine(Zx, k, loads, zn)
                affine(Ox, k, loads, outv)
        else:
            for s in range(ns):
                damp[s] = seg_beta[s] * EAL[s] * (h_v[seg_end[s]] - h_v[seg_start[s]])
            for i in range(n):
                x[i] = d[i] + dt * v[i] + 0.5 * dt**2 * a[i]
            for s in range(ns):
                x[n + s] = P[s] * to_len[s]
            hist = 0
            filled = 0              # history columns written since the mixing (re)started
            converged = False
            for it in range(max_iterations):
                for i in range(n):
                    zt[i] = x[i]
                for i in range(n):
                    f[i] = 0.0
                if corotational:
                    for s in range(ns):
                        Pit[s] = x[n + s] / to_len[s] if own_force else P0[k, s]
                    corotational_loads(every_segment, segments, zt, h_v, c_v, Pit, P0[k], f, local, F, delta)
                else:
                    shape_products(seg_start, seg_end, seg_L, zt, delta, G)
                    for s in range(ns):
                        i0, i1 = seg_start[s], seg_end[s]
                        if shortening:
                            rate = ((c_v * zt[i0 + 1] + h_v[i0 + 1]) * G[s, 0]
                                    + (c_v * zt[i0 + 2] + h_v[i0 + 2]) * G[s, 1]
                                    + (c_v * zt[i1 + 1] + h_v[i1 + 1]) * G[s, 2]
                                    + (c_v * zt[i1 + 2] + h_v[i1 + 2]) * G[s, 3])
                            F[s] = EAL[s] * (delta[s] + seg_beta[s] * rate)
                        else:
                            F[s] = 0.0
                        f[i0] += F[s]
                        f[i1] -= F[s]
                        dP = (x[n + s] / to_len[s] - P0[k, s]) if own_force else 0.0
                        f[i0 + 1] -= dP * G[s, 0]
                        f[i0 + 2] -= dP * G[s, 1]
                        f[i1 + 1] -= dP * G[s, 2]
                        f[i1 + 2] -= dP * G[s, 3]
                for i in range(n):
                    f[i] += loads[i]
                if on_factors is not None:
                    factored_solve(k, f, flayout, fstored, fwork, zn, N, y)
                else:
                    affine(Zx, k, f, zn)
                    affine(Ax, k, f, N)
                for s in range(ns):
                    Pn[s] = N[s] + damp[s] + F[s]
                finite = True
                dz_num, dz_den, dP_num, dP_den = 0.0, 0.0, 0.0, 0.0
                for i in range(n):
                    if not np.isfinite(zn[i]):
                        finite = False
                    dz_num = max(dz_num, abs(zn[i] - zt[i]))
                    dz_den = max(dz_den, abs(zn[i]))
                for s in range(ns):
                    if not np.isfinite(Pn[s]):
                        finite = False
                    dP_num = max(dP_num, abs(Pn[s] - x[n + s] / to_len[s]))
                    dP_den = max(dP_den, abs(Pn[s]))
                if not finite:
                    break
                dz = dz_num / (dz_den + 1e-300)
                dPr = dP_num / (dP_den + scale_P)
                if dz < tol_z and dPr < tol_P:
                    converged = True
                    if on_factors is not None:
                        affine(Ocx, k, y, outv)           # y: the last solve's, for these loads
                    else:
                        affine(Ox, k, f, outv)
                    if corotational:
                        # Only the gauges' segments: their L (e - a) and the bending one's chord lag.
                        corotational_loads(gauge_flat, segments, zn, h_v, c_v, Pn, P0[k], scratch, local, F, delta)
                        for gi in range(gauge_seg.shape[0]):
                            for c in range(2):
                                outv[2 + 2 * gi] += gauge_w[gi, c] * delta[gauge_seg[gi, c]]
                            s = bend_seg[gi]
                            i0, i1 = seg_start[s], seg_end[s]
                            outv[1 + 2 * gi] += bend_w[gi] * chord_lag(seg_L[s], zn[i1] - zn[i0], zn[i1 + 1] - zn[i0 + 1])
                    elif shortening:
                        shape_products(seg_start, seg_end, seg_L, zn, delta, G)
                        for gi in range(gauge_seg.shape[0]):
                            for c in range(2):
                                outv[2 + 2 * gi] += gauge_w[gi, c] * delta[gauge_seg[gi, c]]
                    iterations[j] = it + 1
                    break
                if dz > 1e3 or dPr > 1e3:
                    break
                for i in range(n):
                    gx[i] = zn[i]
                for s in range(ns):
                    gx[n + s] = Pn[s] * to_len[s]
                for i in range(nx):
                    r[i] = gx[i] - x[i]
                if it > 0:
                    col = filled % depth
                    filled += 1
                    for i in range(nx):
                        dR[col, i] = r[i] - prev_r[i]
                        dG[col, i] = gx[i] - prev_g[i]
                    hist = min(hist + 1, depth)
                for i in range(nx):
                    prev_r[i] = r[i]
                    prev_g[i] = gx[i]
                    x[i] = gx[i]
                if hist > 0:
                    anderson_coefficients(dR, hist, r, gamma, Q, R)
                    for c in range(hist):
                        if not np.isfinite(gamma[c]):
                            hist = 0            # an overflowing history: start the mixing afresh
                            filled = 0
                    for i in range(nx):
                        mix[i] = 0.0
                    for c in range(hist):
                        for i in range(nx):
                            mix[i] += dG[c, i] * gamma[c]
                    for i in range(nx):
                        x[i] = gx[i] - mix[i]
            if not converged:
                return j
            for s in range(ns):
                P[s] = Pn[s]
        advance(Gc, ez, S, zn, Snew)
        for o in range(no):
            out_hist[j, o] = outv[o]
        if z_hist.shape[0] > 0:
            for i in range(n):
                z_hist[j, i] = zn[i]
        if P_hist.shape[0] > 0:
            for s in range(ns):
                P_hist[j, s] = P[s]
    return idx.shape[0]
