"""The nonlinear beam terms of the time-domain step, as pseudo-loads.

The linear transfer-matrix step treats every segment as a beam-column whose axial force P0 is
fixed when the configuration is factorized (the quasi-static, rigid-body estimate). Near
buckling that is not good enough (FE crank-rocker at 373 rpm: 8-24 % off a geometrically exact
exudyn model). Two effects are missing, and docs/validation.md's "Engines that agree" section records the
experiment that isolated them (neither alone closes the gap, both together do):

* **Shortening from bending** (foreshortening): the axial strain of a bent segment is
  ``e = (u1 - u0 + Delta) / L`` with ``Delta = 1/2 int w'^2 dx = 1/2 d^T G d`` for the cubic
  segment shape (``d = (w0, theta0, w1, theta1)``, ``G`` the consistent geometric-stiffness
  shape matrix). Near a toggle of the linkage a few tenths of a millimetre of shortening move
  the rocker noticeably, and the shortening oscillates at twice the bending frequency.
* **The step's own axial force** P = EA (e + beta e_dot) (Kelvin-Voigt damping beta), which
  differs from the quasi-static P0 by the elastic inertia and by the shortening itself.

Both enter the cached factorization of P0 as loads at the segment nodes (local frame):
``+F, -F`` on the axial displacements of a segment's two nodes with ``F = EA/L (Delta + beta
Delta_dot)`` (the imposed shortening), and ``-(P - P0) G d`` on its transverse displacements
and rotations (the change of geometric stiffness). The step is then solved by fixed-point
iteration on these pseudo-loads, re-using the factorization (:meth:`tmm_core.TimeDomain`);
the axial force of each iterate is the solver's own segment force plus the damping and
shortening parts, so it is the equilibrium force (displacement differences times EA/L would
lose digits).

This is the von Karman beam in the moving frame of each link: strain u' + w'^2/2, bending
equilibrium with the actual axial force. Its error against a geometrically exact beam is of
order (slope)^2 of the elastic deflection relative to the link. On the FE crank-rocker that
error, amplified near resonances and at light damping, is what parted the model from exudyn
once the rocker's segments turned more than about 4 deg (docs/light_damping.md). The
co-rotational strain measure (:func:`corotational_pseudo_loads`) removes it: each segment keeps
the cubic beam in a frame that turns with its chord, exactly, with its Kelvin-Voigt damping on its
rotations against the chord; the pseudo-loads are then the difference between its exact forces
and the solver's linear ones (elastic and damping), and their derivatives (the periodic solver's
linearization, the reduced model's Jacobian) are exact, written forward-mode by hand. It
is the default (:data:`tmm_core.discretization.DEFAULT_TERMS`). Its end rotations against the
chord exceed the linear segment's by the chord lag (:func:`chord_lag`), which the gauges' bending
reads (:func:`tmm_core.discretization.bending_sampling`).

Owns: the nonlinear beam terms as pseudo-loads, in each strain measure, and their derivatives.
Boundaries: no step driver.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Segments:
    """Segment data of a stacked node vector (3 local DOFs ``(u, w, theta)`` per node).

    ``start``/``end``: index of the segment's first/last node's ``u`` in the node vector;
    ``length`` [m], ``EA`` [N], ``beta`` [s] (stiffness-proportional damping) per segment;
    ``EI`` [N m^2] per segment (the co-rotational prototype's bending; None where not given)."""

    start: np.ndarray
    end: np.ndarray
    length: np.ndarray
    EA: np.ndarray
    beta: np.ndarray
    EI: np.ndarray | None = None

    @property
    def stiffness(self) -> np.ndarray:
        """EA/L [N/m] per segment."""
        return self.EA / self.length


def shape_products(seg: Segments, z: np.ndarray):
    """``(Delta, Gd)``: the shortening ``1/2 d^T G d`` [m] of every segment and the four
    components of ``G d`` (``G`` = 1/(30 L) [[36, 3L, -36, 3L], [3L, 4L^2, -3L, -L^2],
    [-36, -3L, 36, -3L], [3L, -L^2, -3L, 4L^2]])."""
    L = seg.length
    w0, t0, w1, t1 = z[..., seg.start + 1], z[..., seg.start + 2], z[..., seg.end + 1], z[..., seg.end + 2]
    dw = w0 - w1
    g0 = (36.0 * dw + 3.0 * L * (t0 + t1)) / (30.0 * L)
    g1 = (3.0 * dw + L * (4.0 * t0 - t1)) / 30.0
    g3 = (3.0 * dw + L * (4.0 * t1 - t0)) / 30.0
    delta = 0.5 * (dw * g0 + t0 * g1 + t1 * g3)
    return delta, (g0, g1, -g0, g3)


def rate(seg: Segments, v: np.ndarray, Gd) -> np.ndarray:
    """Time derivative of the shortening, ``v_d^T G d`` [m/s], for node velocities ``v``."""
    return (v[..., seg.start + 1] * Gd[0] + v[..., seg.start + 2] * Gd[1] + v[..., seg.end + 1] * Gd[2]
            + v[..., seg.end + 2] * Gd[3])


#: The segment's strain measure in :func:`pseudo_loads`: the second-order one (the model), none
#: (the shortening left out; experiments), and two prototypes of issue 34 (numpy step only).
STRAIN_MEASURES = ("second_order", "none", "exact", "corotational")


def pseudo_loads(seg: Segments, z: np.ndarray, v: np.ndarray, P: np.ndarray, P0: np.ndarray,
                 strain: str = "second_order"):
    """Nodal pseudo-loads (stacked local node vector) of the shortening and of the axial-force
    change ``P - P0`` for displacements ``z`` and velocities ``v``; also returns the shortening
    force ``F = EA/L (Delta + beta Delta_dot)`` [N] and ``Delta`` [m] per segment.
    ``strain`` (:data:`STRAIN_MEASURES`): 'none' leaves the shortening out (F = 0; for
    experiments); 'exact' takes the geometrically exact axial strain of the segment instead of
    the second-order one (:func:`exact_pseudo_loads`); 'corotational' a segment exact in its
    rotation (:func:`corotational_pseudo_loads`)."""
    if strain == "exact":
        return exact_pseudo_loads(seg, z, v, P, P0)
    if strain == "corotational":
        return corotational_pseudo_loads(seg, z, v, P, P0)
    shortening = strain != "none"
    delta, Gd = shape_products(seg, z)
    F = seg.stiffness * (delta + seg.beta * rate(seg, v, Gd)) if shortening else np.zeros_like(delta)
    f = np.zeros(np.shape(z))
    np.add.at(f, (..., seg.start), F)
    np.add.at(f, (..., seg.end), -F)
    dP = P - P0
    for offset, idx, g in ((1, seg.start, Gd[0]), (2, seg.start, Gd[1]), (1, seg.end, Gd[2]), (2, seg.end, Gd[3])):
        np.add.at(f, (..., idx + offset), -dP * g)
    return f, F, delta


def geometric_matrices(L):
    """Consistent geometric-stiffness matrices ``G`` (n_seg, 4, 4) of cubic segments of length
    ``L`` [m] on ``(w0, theta0, w1, theta1)``."""
    L = np.asarray(L, dtype=float)[:, None, None]
    base = np.array([[36.0, 3.0, -36.0, 3.0], [3.0, 4.0, -3.0, -1.0], [-36.0, -3.0, 36.0, -3.0], [3.0, -1.0, -3.0, 4.0]])
    powers = np.array([[0, 1, 0, 1], [1, 2, 1, 2], [0, 1, 0, 1], [1, 2, 1, 2]])
    return base * L ** powers / (30.0 * L)


def _dof_index(seg: Segments) -> np.ndarray:
    """Node-vector index of ``d = (w0, theta0, w1, theta1)`` of every segment, ``(n_seg, 4)``."""
    return np.stack([seg.start + 1, seg.start + 2, seg.end + 1, seg.end + 2], axis=1)


def linearization(seg: Segments, n: int, c_v: float, z, v, P, P0):
    """Derivatives of the pseudo-loads ``f`` and the shortening force ``F`` at ``(z, v, P)``, for
    the linearized step (periodic shooting): ``(f_z, f_P, f_h, F_z, F_h)`` with ``v = c_v z + h``
    (``h`` the velocity history): ``f_z`` (n, n), ``f_P`` (n, n_seg), ``f_h`` (n, n),
    ``F_z`` (n_seg, n), ``F_h`` (n_seg, n)."""
    ns = len(seg.length)
    G = geometric_matrices(seg.length)
    idx = _dof_index(seg)
    d, vd = z[idx], v[idx]                                 # (n_seg, 4)
    a = np.einsum("sij,sj->si", G, d)                      # G d
    b = np.einsum("sij,sj->si", G, vd)                     # G v_d
    k, beta = seg.stiffness, seg.beta
    F_d = np.zeros((ns, n))                                # dF/dz at fixed v
    F_v = np.zeros((ns, n))                                # dF/dv
    rows = np.arange(ns)[:, None]
    np.add.at(F_d, (rows, idx), (k[:, None] * (a + beta[:, None] * b)))
    np.add.at(F_v, (rows, idx), (k * beta)[:, None] * a)
    Su = np.zeros((n, ns))                                 # scatter of F onto the axial DOFs
    Su[seg.start, np.arange(ns)] += 1.0
    Su[seg.end, np.arange(ns)] -= 1.0
    F_z = F_d + c_v * F_v
    f_z = Su @ F_z
    dP = P - P0
    for s_ in range(ns):
        f_z[np.ix_(idx[s_], idx[s_])] -= dP[s_] * G[s_]
    f_P = np.zeros((n, ns))
    np.add.at(f_P, (idx, np.broadcast_to(np.arange(ns)[:, None], idx.shape)), -a)
    return f_z, f_P, Su @ F_v, F_z, F_v


# -- prototype (issue 34): the exact strain of the segment instead of the second-order one ----------
#: Gauss-Legendre points on [0, 1] and weights (summing to 1) of the exact-strain quadrature.
_GAUSS_X, _GAUSS_W = (0.5 * (np.polynomial.legendre.leggauss(5)[0] + 1.0), 0.5 * np.polynomial.legendre.leggauss(5)[1])


def _slope_rows(L):
    """``B`` (n_seg, n_gauss, 4): the slope ``w'`` at each Gauss point of each segment is
    ``B @ (w0, theta0, w1, theta1)`` (cubic Hermite shape)."""
    x = _GAUSS_X[None, :]
    L = np.asarray(L, dtype=float)[:, None]
    shape = np.shape(L * x)
    return np.stack([(-6 * x + 6 * x**2) / L, np.broadcast_to(1 - 4 * x + 3 * x**2, shape), (6 * x - 6 * x**2) / L,
                     np.broadcast_to(-2 * x + 3 * x**2, shape)], axis=-1)


def exact_strain(seg: Segments, z: np.ndarray, v: np.ndarray):
    """Mean exact axial strain of every segment relative to its linear part and the derivatives
    the pseudo-loads need, for node displacements ``z`` and velocities ``v`` (1-D):
    ``(excess, excess_rate, c_a, g)``: ``excess = e - a`` with ``e`` the segment's mean of
    ``sqrt((1 + a)^2 + w'^2) - 1`` and ``a = (u1 - u0)/L`` (in the second-order theory this is
    ``Delta / L``), its rate, ``c_a = de/da`` and ``g = L de/dd`` (n_seg, 4)."""
    L = seg.length
    idx = np.stack([seg.start + 1, seg.start + 2, seg.end + 1, seg.end + 2], axis=1)
    B = _slope_rows(L)
    wp = np.einsum("sgj,sj->sg", B, z[idx])
    wp_dot = np.einsum("sgj,sj->sg", B, v[idx])
    a = ((z[seg.end] - z[seg.start]) / L)[:, None]
    a_dot = ((v[seg.end] - v[seg.start]) / L)[:, None]
    root = np.sqrt((1 + a) ** 2 + wp**2)
    W = _GAUSS_W[None, :]
    excess = np.sum(W * wp**2 / (root + 1 + a), axis=1)              # e - a, without cancellation
    rate = np.sum(W * (a_dot * ((1 + a) - root) / root + wp * wp_dot / root), axis=1)
    c_a = np.sum(W * (1 + a) / root, axis=1)
    g = L[:, None] * np.einsum("sg,sgj->sj", W * wp / root, B)
    return excess, rate, c_a, g


def exact_pseudo_loads(seg: Segments, z: np.ndarray, v: np.ndarray, P: np.ndarray, P0: np.ndarray):
    """:func:`pseudo_loads` with the segment's exact strain (prototype of issue 34). The strain
    energy of a segment is ``1/2 EA L e^2`` with ``e`` its mean exact strain (:func:`exact_strain`)
    and the physical axial force ``P = EA (e + beta e_dot)``. Nodal forces: ``P c_a`` on the axial
    displacements (the linear solve carries ``EA (a + beta a_dot)``) and ``P g`` on ``(w0, theta0,
    w1, theta1)`` (the factorization carries ``P0 G d``). Returns ``(f, F, Delta)`` as
    :func:`pseudo_loads`, with ``F = EA ((e - a) + beta (e - a)_dot)`` (the force to add to the
    solver's segment force for P) and ``Delta = L (e - a)``."""
    excess, rate, c_a, g = exact_strain(seg, z, v)
    EA = seg.EA
    F = EA * (excess + seg.beta * rate)
    # Axial: P c_a - (solver force) = P c_a - (P - F) = F + P (c_a - 1).
    F_ax = F + P * (c_a - 1.0)
    f = np.zeros(np.shape(z))
    np.add.at(f, seg.start, F_ax)
    np.add.at(f, seg.end, -F_ax)
    _, Gd = shape_products(seg, z)
    for j, (offset, idx) in enumerate(((1, seg.start), (2, seg.start), (1, seg.end), (2, seg.end))):
        np.add.at(f, idx + offset, -(P * g[:, j] - P0 * Gd[j]))
    return f, F, excess * seg.length


# -- prototype (issue 34): a segment exact in its rotation (co-rotational) ---------------------------
def _bending_forces(EI, L, P, t0, t1):
    """End moments ``(m0, m1)`` [N m] of a cubic segment whose end rotations against its chord are
    ``t0, t1`` [rad], with the geometric stiffness of its axial force ``P`` [N]: ``(K + P G)`` on
    the rotations, ``K = EI/L [[4, 2], [2, 4]]``, ``G = L/30 [[4, -1], [-1, 4]]``."""
    k, g = EI / L, P * L / 30.0
    return k * (4 * t0 + 2 * t1) + g * (4 * t0 - t1), k * (2 * t0 + 4 * t1) + g * (4 * t1 - t0)


def corotational_pseudo_loads(seg: Segments, z: np.ndarray, v: np.ndarray, P: np.ndarray, P0: np.ndarray):
    """:func:`pseudo_loads` of a co-rotational segment (``dynamic_terms`` with 'corotational').

    Each segment carries the cubic beam of the second-order model in a frame that turns with its
    chord, exactly: chord length ``l`` and angle ``b`` from the end displacements (``l cos b = L +
    u1 - u0``, ``l sin b = w1 - w0``), end rotations against the chord ``t_i = theta_i - b``, and
    the strain ``e = (l - L + Delta_c) / L`` with ``Delta_c = 1/2 t^T G t`` the shortening of the
    cubic relative to its chord. Its nodal forces are the gradient of ``1/2 EA L e^2 + 1/2 t^T K
    t`` with the physical axial force ``P = EA (e + beta e')``, plus the Kelvin-Voigt moments
    ``beta K t'`` on the rotations against the chord. To second order in the rotations they are
    the second-order model's; the pseudo-loads are the difference between these forces and the
    solver's (``EA (a + beta a')`` axially, ``K (d + beta d') + P0 G d`` in bending with ``d`` the
    end rotations against the linearized chord, ``theta_i - dw/L``; ``a = (u1 - u0)/L``). The
    solver's damping must be taken out with its stiffness: left in the link frame, ``beta K``
    acts on the rate of the chord lag ``dw/L - b`` with a stiffness 12 EI / L^3, a damping that
    grows as the mesh is refined (docs/light_damping.md). Returns ``(f, F, Delta)`` as
    :func:`pseudo_loads`, with ``Delta = L (e - a)``."""
    idx = segment_dofs(seg)
    loads, F, excess, _ = _corotational_local(seg, z[idx], v[idx], P, P0)
    f = np.zeros(np.shape(z))
    np.add.at(f, idx, loads)
    return f, F, excess


def chord_lag(seg: Segments, z: np.ndarray) -> np.ndarray:
    """The chord lag ``psi = dw/L - b`` [rad] of every segment (S,), for node displacements ``z``
    (1-D): how much the co-rotational segment's end rotations against its chord (``theta_i - b``,
    ``b`` the chord's exact angle) exceed the linear segment's (``theta_i - dw/L``). The gauges'
    bending reads it (:func:`tmm_core.discretization.bending_sampling`)."""
    L = seg.length
    dw = z[seg.end + 1] - z[seg.start + 1]
    return dw / L - np.arctan2(dw, L + z[seg.end] - z[seg.start])


def segment_dofs(seg: Segments) -> np.ndarray:
    """Node-vector index of every segment's ``(u0, w0, theta0, u1, w1, theta1)``, ``(n_seg, 6)``."""
    return np.stack([seg.start, seg.start + 1, seg.start + 2, seg.end, seg.end + 1, seg.end + 2], axis=1)


def _corotational_local(seg: Segments, zl: np.ndarray, vl: np.ndarray, P, P0):
    """The co-rotational segments' pseudo-loads on their own ``(u0, w0, theta0, u1, w1, theta1)``
    (n_seg, 6), their shortening force ``F`` [N], ``Delta = L (e - a)`` [m] and the axial force
    they carry [N], from their local displacements ``zl`` and velocities ``vl`` (n_seg, 6)
    (:func:`corotational_pseudo_loads`). ``P`` None: the physical axial force of the same state,
    ``EA/L (u1 - u0 + beta (u1 - u0)') + F`` (the reduced model's, which has no axial-force
    unknown)."""
    if seg.EI is None:
        raise ValueError("the co-rotational segment needs the segments' EI")
    L, EA, EI, beta = seg.length, seg.EA, seg.EI, seg.beta
    du, dw, q0, q1 = zl[:, 3] - zl[:, 0], zl[:, 4] - zl[:, 1], zl[:, 2], zl[:, 5]
    dud, dwd = vl[:, 3] - vl[:, 0], vl[:, 4] - vl[:, 1]
    l = np.hypot(L + du, dw)
    c, s = (L + du) / l, dw / l
    b = np.arctan2(dw, L + du)
    bd = (c * dwd - s * dud) / l
    t0, t1 = q0 - b, q1 - b
    t0d, t1d = vl[:, 2] - bd, vl[:, 5] - bd
    # e L - (u1 - u0) = (l - L - du) + Delta_c; l - L - du = dw^2 / (l + L + du) without cancellation
    # where the chord points forward, l - (L + du) itself where a diverging iterate folded it back.
    forward = L + du > 0
    chord = np.where(forward, dw * dw / np.where(forward, l + L + du, 1.0), l - (L + du))
    excess = chord + L / 60.0 * (4 * t0 * t0 - 2 * t0 * t1 + 4 * t1 * t1)
    excess_rate = (c - 1.0) * dud + s * dwd + L / 30.0 * ((4 * t0 - t1) * t0d + (4 * t1 - t0) * t1d)
    F = EA / L * (excess + beta * excess_rate)
    if P is None:
        P = EA / L * (du + beta * dud) + F
    # The energy's gradient: P on the chord's length, the end moments on the rotations and,
    # through the chord's angle, -(m0 + m1) on it.
    m0, m1 = _bending_forces(EI, L, P, t0, t1)
    d0, d1 = _bending_forces(EI * beta, L, 0.0, t0d, t1d)
    m0, m1 = m0 + d0, m1 + d1
    g_u = P * c + (m0 + m1) * s / l
    g_w = P * s - (m0 + m1) * c / l
    # The solver's: EA (a + beta a') = P - F axially; K d + P0 G d in bending (K d: the same
    # cubic with the chord's angle linearized, dw / L; G d: shape_products').
    k0, k1 = _bending_forces(EI, L, 0.0, q0 - dw / L + beta * (vl[:, 2] - dwd / L), q1 - dw / L + beta * (vl[:, 5] - dwd / L))
    g0 = (-36.0 * dw + 3.0 * L * (q0 + q1)) / (30.0 * L)
    g1 = (-3.0 * dw + L * (4.0 * q0 - q1)) / 30.0
    g3 = (-3.0 * dw + L * (4.0 * q1 - q0)) / 30.0
    axial = g_u - (P - F)
    shear = g_w - (-(k0 + k1) / L - P0 * g0)
    loads = np.stack([axial, shear, -(m0 - k0 - P0 * g1), -axial, -shear, -(m1 - k1 - P0 * g3)], axis=1)
    return loads, F, excess, P


def _corotational_tangent(seg: Segments, zl: np.ndarray, vl: np.ndarray, P, P0, own: bool = False):
    """The exact derivatives of :func:`_corotational_local`: ``(loads_z, loads_v, loads_P, F_z,
    F_v)``, those of the pseudo-loads and of the shortening force by the segment's six
    displacements and six velocities (n_seg, 6, 6 and n_seg, 6) and of the pseudo-loads by its
    axial force ``P`` [N] (n_seg, 6). ``own``: ``P`` is the physical axial force of the state
    (``_corotational_local``'s with ``P`` None), its dependence on the state then in the
    derivatives (and ``loads_P`` zero), as in the compiled twin. Forward-mode by hand: every
    intermediate of :func:`_corotational_local` carries its gradient over ``(x, y, q0, q1, x', y',
    q0', q1', P)`` with ``x = L + u1 - u0``, ``y = w1 - w0``; tests/test_corotational.py checks it
    against central differences of :func:`_corotational_local`."""
    L, EA, EI, beta = seg.length, seg.EA, seg.EI, seg.beta
    ns = len(L)
    x, y, q0, q1 = L + zl[:, 3] - zl[:, 0], zl[:, 4] - zl[:, 1], zl[:, 2], zl[:, 5]
    xd, yd = vl[:, 3] - vl[:, 0], vl[:, 4] - vl[:, 1]
    P0 = np.broadcast_to(np.asarray(P0, dtype=float), (ns,))
    unit = np.eye(9)
    X, Y, Q0, Q1, XD, YD, Q0D, Q1D, PP = (np.broadcast_to(unit[i], (ns, 9)) for i in range(9))
    col = lambda a: np.asarray(a)[:, None]          # noqa: E731  a per-segment scalar against a gradient
    l2 = x * x + y * y
    l = np.sqrt(l2)
    c, s = x / l, y / l
    b = np.arctan2(y, x)
    grad_b = col(-y / l2) * X + col(x / l2) * Y
    bd = (x * yd - y * xd) / l2
    grad_bd = col((yd - 2 * x * bd) / l2) * X + col((-xd - 2 * y * bd) / l2) * Y + col(-y / l2) * XD + col(x / l2) * YD
    t0, t1 = q0 - b, q1 - b
    t0d, t1d = vl[:, 2] - bd, vl[:, 5] - bd
    g_t0, g_t1, g_t0d, g_t1d = Q0 - grad_b, Q1 - grad_b, Q0D - grad_bd, Q1D - grad_bd
    h0, h1 = L / 30.0 * (4 * t0 - t1), L / 30.0 * (4 * t1 - t0)
    g_h0, g_h1 = col(L / 30.0) * (4 * g_t0 - g_t1), col(L / 30.0) * (4 * g_t1 - g_t0)
    g_excess = col(c - 1.0) * X + col(s) * Y + col(h0) * g_t0 + col(h1) * g_t1
    g_rate = (col(-s * bd) * X + col(c * bd) * Y + col(c - 1.0) * XD + col(s) * YD + col(h0) * g_t0d
              + col(h1) * g_t1d + col(t0d) * g_h0 + col(t1d) * g_h1)
    g_F = col(EA / L) * (g_excess + col(beta) * g_rate)
    if own:                 # the physical axial force of the state: its gradient too
        PP = col(EA / L) * (X + col(beta) * XD) + g_F
    P = np.broadcast_to(np.asarray(P, dtype=float), (ns,))
    k00, k01 = 4 * EI / L, 2 * EI / L
    r0, r1 = t0 + beta * t0d, t1 + beta * t1d
    g_r0, g_r1 = g_t0 + col(beta) * g_t0d, g_t1 + col(beta) * g_t1d
    m0, m1 = k00 * r0 + k01 * r1 + P * h0, k01 * r0 + k00 * r1 + P * h1
    g_m0 = col(k00) * g_r0 + col(k01) * g_r1 + col(h0) * PP + col(P) * g_h0
    g_m1 = col(k01) * g_r0 + col(k00) * g_r1 + col(h1) * PP + col(P) * g_h1
    M, g_M = m0 + m1, g_m0 + g_m1
    g_c, g_s = col(s * s / l) * X - col(c * s / l) * Y, col(-c * s / l) * X + col(c * c / l) * Y
    g_sl = col(-2 * c * s / l2) * X + col((c * c - s * s) / l2) * Y          # of s / l
    g_cl = col((s * s - c * c) / l2) * X + col(-2 * c * s / l2) * Y          # of c / l
    g_axial = col(c - 1.0) * PP + col(P) * g_c + col(s / l) * g_M + col(M) * g_sl + g_F
    # The solver's bending: K (d + beta d') with d the rotations against the linearized chord, and
    # P0 G d (shape_products', on (w0, theta0, w1, theta1) = (0, q0, y, q1)).
    g_e0 = Q0 - col(1 / L) * Y + col(beta) * (Q0D - col(1 / L) * YD)
    g_e1 = Q1 - col(1 / L) * Y + col(beta) * (Q1D - col(1 / L) * YD)
    g_kb0, g_kb1 = col(k00) * g_e0 + col(k01) * g_e1, col(k01) * g_e0 + col(k00) * g_e1
    g_g0 = col(-1.2 / L) * Y + 0.1 * (Q0 + Q1)
    g_g1 = -0.1 * Y + col(L / 30.0) * (4 * Q0 - Q1)
    g_g3 = -0.1 * Y + col(L / 30.0) * (4 * Q1 - Q0)
    g_shear = (col(s) * PP + col(P) * g_s - col(c / l) * g_M - col(M) * g_cl + col(1 / L) * (g_kb0 + g_kb1)
               + col(P0) * g_g0)
    g_mom0, g_mom1 = -(g_m0 - g_kb0 - col(P0) * g_g1), -(g_m1 - g_kb1 - col(P0) * g_g3)
    grads = np.stack([g_axial, g_shear, g_mom0, -g_axial, -g_shear, g_mom1], axis=1)     # (ns, 6, 9)
    # (x, y, q0, q1) of (u0, w0, theta0, u1, w1, theta1), and the rates alike.
    to_dofs = np.zeros((4, 6))
    to_dofs[0, [0, 3]] = -1.0, 1.0
    to_dofs[1, [1, 4]] = -1.0, 1.0
    to_dofs[2, 2] = to_dofs[3, 5] = 1.0
    return (grads[..., :4] @ to_dofs, grads[..., 4:8] @ to_dofs, grads[..., 8], g_F[:, :4] @ to_dofs,
            g_F[:, 4:8] @ to_dofs)


def corotational_linearization(seg: Segments, n: int, c_v: float, z, v, P, P0):
    """:func:`linearization` of the co-rotational pseudo-loads (the same five derivatives, dense),
    from each segment's exact derivatives in its six degrees of freedom, its velocities and its
    axial force (:func:`_corotational_tangent`)."""
    idx = segment_dofs(seg)
    ns = len(seg.length)
    f_d, f_v, f_P_local, F_d, F_v = _corotational_tangent(seg, z[idx], v[idx], P, P0)
    f_z, f_h = np.zeros((n, n)), np.zeros((n, n))
    F_z, F_h = np.zeros((ns, n)), np.zeros((ns, n))
    f_P = np.zeros((n, ns))
    rows = np.arange(ns)
    for a in range(6):
        np.add.at(f_P, (idx[:, a], rows), f_P_local[:, a])
        np.add.at(F_z, (rows, idx[:, a]), F_d[:, a] + c_v * F_v[:, a])
        np.add.at(F_h, (rows, idx[:, a]), F_v[:, a])
        for b_ in range(6):
            np.add.at(f_z, (idx[:, a], idx[:, b_]), f_d[:, a, b_] + c_v * f_v[:, a, b_])
            np.add.at(f_h, (idx[:, a], idx[:, b_]), f_v[:, a, b_])
    return f_z, f_P, f_h, F_z, F_h


def corotational_node_forces(seg: Segments, zl: np.ndarray, vl: np.ndarray, jacobian: bool = True):
    """The co-rotational segments' nonlinear internal forces on their six dofs beyond the linear
    ones (``K q`` and the axial ``EA/L (u1 - u0 + beta (u1 - u0)')``), at their physical axial
    force, for local displacements and velocities ``zl, vl`` (..., n_seg, 6): ``(g, P, Delta)``
    and, with ``jacobian``, ``g``'s exact derivatives by ``zl`` and ``vl`` (..., n_seg, 6, 6)
    (:func:`_corotational_tangent`, the axial force's dependence on the state included). The
    reduced model's second-order term (:class:`tmm_core.reduced_periodic.ReducedModel`): ``-`` the
    pseudo-loads with P0 = 0."""
    shape = zl.shape[:-1]
    flat = int(np.prod(shape))
    tile = lambda x: np.broadcast_to(x, shape).reshape(flat)  # noqa: E731  per segment, for every stage
    tiled = Segments(seg.start, seg.end, tile(seg.length), tile(seg.EA), tile(seg.beta), tile(seg.EI))
    z2, v2 = zl.reshape(flat, 6), vl.reshape(flat, 6)
    loads, _, excess, P = _corotational_local(tiled, z2, v2, None, 0.0)
    out = (-loads.reshape(*shape, 6), P.reshape(shape), excess.reshape(shape))
    if not jacobian:
        return out
    g_z, g_v, _, _, _ = _corotational_tangent(tiled, z2, v2, P, 0.0, own=True)
    g_z, g_v = -g_z, -g_v
    return (*out, g_z.reshape(*shape, 6, 6), g_v.reshape(*shape, 6, 6))
