"""7x7 transfer matrices of planar Euler-Bernoulli links (after Shin 1986, ch. 3).

State vector and sign convention
--------------------------------
The state at a station of a link is ``S = (u, w, theta, M, V, N, 1)`` in the link's local
frame (x along the link from its start joint to its end joint, y = x rotated +90 deg):

==========  ===============================================================  =====
``u``       displacement along local x                                        m
``w``       displacement along local y                                        m
``theta``   rotation of the cross-section, counter-clockwise positive (= dw/dx) rad
``M``       bending moment on the positive cut face, counter-clockwise positive N m
``V``       transverse force on the positive cut face, along +y               N
``N``       axial force on the positive cut face, along +x (tension positive) N
==========  ===============================================================  =====

The *positive cut face* is the face whose outward normal is +x, i.e. (M, V, N) are the
actions of the part of the link beyond the station on the part before it. With this
convention the small-deflection beam-column equations read::

    u' = N/EA          N' = -p        (p: distributed axial load per length, +x)
    w' = theta         V' = -q        (q: distributed transverse load per length, +y)
    theta' = M/EI      M' = -V + P*theta   (P: axial force of the segment, tension > 0)

so ``M > 0`` sags the link (w'' > 0) and puts the ``-y`` face in tension:
``sigma(y) = N/A - M*y/I``.

Relation to Shin (1986): his rotation and moment are clockwise positive,
``theta_Shin = -theta`` and ``M_Shin = -M``; V and N are the same. Everything else
(ordering, point-matrix convention "column 7 holds minus the applied load", frame rotation
sign) follows Shin.

A transfer matrix maps the state at its input station to the state at its output station:
``S_out = T @ S_in``. *Point-type* matrices (point loads, springs, inertia) leave (u, w, theta)
unchanged and change the forces by ``f_out = f_in + K z - F_ext``.

All functions broadcast over leading ("batch") dimensions and return arrays of shape
``(..., 7, 7)``.

Field matrix
------------
For every axial force P the field matrix is written with the Stumpff-type functions
``c_k(s) = sum_n s**n / (2n+k)!`` of ``s = P L**2 / EI`` (signed), which are entire
functions of ``s``: ``c0 = cosh sqrt(s)`` for tension, ``cos sqrt(-s)`` for compression and
1 for ``P = 0``. The P = 0, tension (sinh/cosh) and compression (sin/cos) forms of Shin's
Eqs. 3.14-3.16 are therefore one formula, exactly continuous as P -> 0; a power series is used
for ``|s| < 4`` where the closed forms cancel.

The load column follows from integrating the state equations above. Shin's printed axial
load terms (F1, F6 of Eq. 3.17) are mutually inconsistent; here ``N1 = N0 - p L`` and
``u1 = u0 + N0 L/EA - p L**2/(2 EA)``, which a hanging-bar test checks.

Owns: the 7x7 transfer matrices. Boundaries: no chaining (tmm_core.riccati).
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError

# Indices into the 7-state (u, w, theta, M, V, N, 1).
U, W, TH, M, V, N, ONE = range(7)
#: displacement part z = (u, w, theta)
Z_IDX = np.array([U, W, TH])
#: force part in *conjugate* order f = (N, V, M), so that f[k] does work on z[k]
F_IDX = np.array([N, V, M])

#: Below this |s| the Stumpff functions are summed as series (the compiled twin,
#: tmm_core.compiled.dense.stumpff, uses the same limit and table).
SERIES_LIMIT = 4.0
SERIES_TERMS = 24
INV_FACT = [1.0 / math.factorial(k) for k in range(2 * SERIES_TERMS + 6)]


def stumpff(s):
    """Return ``(c0, c1, c2, c3, c4)`` with ``c_k(s) = sum_{n>=0} s**n / (2n+k)!``.

    ``s`` may be any real array. ``c0 = cosh(sqrt(s))``, ``c1 = sinh(sqrt(s))/sqrt(s)`` for
    ``s > 0`` and the circular counterparts for ``s < 0``. The recurrence
    ``c_k = 1/k! + s c_{k+2}`` links them.
    """
    s = np.asarray(s, dtype=float)
    if np.any(s > 700.0**2):
        raise InputError(
            f"segment tension parameter P*L^2/EI = {float(np.max(s)):.4g} overflows cosh; "
            "split the link into more segments")
    small = np.abs(s) < SERIES_LIMIT
    ss = np.where(small, s, 0.0)
    # Horner evaluation of c3 and c4 (series), exact to round-off for |s| < 4.
    c3s = np.zeros_like(ss)
    c4s = np.zeros_like(ss)
    for n in range(SERIES_TERMS, -1, -1):
        c3s = c3s * ss + INV_FACT[2 * n + 3]
        c4s = c4s * ss + INV_FACT[2 * n + 4]
    c1s = 1.0 + ss * c3s
    c2s = 0.5 + ss * c4s
    c0s = 1.0 + ss * c2s

    sl = np.where(small, 1.0, s)  # avoid 0/0 in the closed forms where the series is used
    r = np.sqrt(np.abs(sl))
    pos = sl > 0
    c0l = np.where(pos, np.cosh(np.where(pos, r, 0.0)), np.cos(r))
    c1l = np.where(pos, np.sinh(np.where(pos, r, 0.0)), np.sin(r)) / r
    c2l = (c0l - 1.0) / sl
    c3l = (c1l - 1.0) / sl
    c4l = (c2l - 0.5) / sl
    return tuple(np.where(small, a, b) for a, b in
                 ((c0s, c0l), (c1s, c1l), (c2s, c2l), (c3s, c3l), (c4s, c4l)))


def _empty(*arrays) -> np.ndarray:
    shape = np.broadcast_shapes(*(np.shape(a) for a in arrays))
    return np.zeros(shape + (7, 7))


def field_matrix(length, EA, EI, axial_force=0.0, q=0.0, p=0.0, chord_rotation=0.0):
    """Field matrix of a straight Euler-Bernoulli segment (beam-column), shape ``(..., 7, 7)``.

    Parameters
    ----------
    length : segment length L [m]
    EA, EI : axial [N] and bending [N m^2] stiffness
    axial_force : P [N], tension positive, taken from the previous iteration (beam-column
        coupling). ``P = 0`` gives Shin's Eq. 3.14.
    q, p : distributed load per unit undeformed length [N/m], transverse (+y) and axial (+x),
        in the *link* frame.
    chord_rotation : beta [rad], rotation of the segment chord relative to the link frame,
        from the previous iteration of the large-deflection mode (0 for small deflection).
        The segment is then a small-deflection beam-column in its rotated chord frame, with
        ``P`` the axial force along the chord; its end displacement includes the exact rigid
        rotation of the chord. This is the co-rotational form of Shin's ch. 4 correction
        (his alpha = theta/2 is an approximation of beta).
    """
    L = np.asarray(length, dtype=float)
    EA = np.asarray(EA, dtype=float)
    EI = np.asarray(EI, dtype=float)
    P = np.asarray(axial_force, dtype=float)
    q = np.asarray(q, dtype=float)
    p = np.asarray(p, dtype=float)
    beta = np.asarray(chord_rotation, dtype=float)

    s = P * L**2 / EI
    c0, c1, c2, c3, c4 = stumpff(s)
    cb, sb = np.cos(beta), np.sin(beta)
    # Loads resolved in the chord frame.
    pc = cb * p + sb * q
    qc = -sb * p + cb * q

    T = _empty(L, EA, EI, P, q, p, beta)
    # Local increments along the chord: du_c, dw_c as rows over the state columns.
    du = np.zeros(T.shape[:-2] + (7,))
    dw = np.zeros(T.shape[:-2] + (7,))
    du[..., N] = L / EA * cb
    du[..., V] = L / EA * sb
    du[..., ONE] = -pc * L**2 / (2.0 * EA)
    dw[..., TH] = L * c1
    dw[..., M] = L**2 * c2 / EI
    dw[..., N] = L**3 * c3 / EI * sb          # V_c = -sb*N + cb*V
    dw[..., V] = -L**3 * c3 / EI * cb
    dw[..., ONE] = qc * L**4 * c4 / EI - L * c1 * beta   # theta_local = theta - beta

    T[..., U, :] = cb[..., None] * du - sb[..., None] * dw
    T[..., W, :] = sb[..., None] * du + cb[..., None] * dw
    T[..., U, U] += 1.0
    T[..., W, W] += 1.0
    T[..., U, ONE] += L * (cb - 1.0)
    T[..., W, ONE] += L * sb

    T[..., TH, TH] = c0
    T[..., TH, M] = L * c1 / EI
    T[..., TH, N] = L**2 * c2 / EI * sb
    T[..., TH, V] = -L**2 * c2 / EI * cb
    T[..., TH, ONE] = beta * (1.0 - c0) + qc * L**3 * c3 / EI

    k2L = P * L * c1
    T[..., M, TH] = k2L
    T[..., M, M] = c0
    T[..., M, N] = L * c1 * sb
    T[..., M, V] = -L * c1 * cb
    T[..., M, ONE] = qc * L**2 * c2 - k2L * beta

    T[..., V, V] = 1.0
    T[..., V, ONE] = -q * L
    T[..., N, N] = 1.0
    T[..., N, ONE] = -p * L
    T[..., ONE, ONE] = 1.0
    return T


def point_matrix(force=(0.0, 0.0, 0.0), stiffness=None):
    """Point matrix of a node carrying an external load and/or a stiffness to ground.

    ``force`` : external load ``(F_u, F_w, M_z)`` applied at the node, in the local frame
        [N, N, N m], shape ``(..., 3)``. It enters column 7 with a minus sign (Shin Eq. 3.21).
    ``stiffness`` : ``(..., 3, 3)`` stiffness to ground in the local frame acting on
        ``z = (u, w, theta)``, rows in conjugate force order ``(N, V, M)`` [N/m, N/rad, N m/rad].
        A spring exerts ``-K z`` on the node, so ``f_out = f_in + K z``. Used for translational
        springs (Shin Eq. 3.25 with a sliding end) and the inertial "dynamic stiffness" of
        implicit time integration (Shin Eq. 3.47).
    """
    force = np.asarray(force, dtype=float)
    shape = force.shape[:-1]
    if stiffness is not None:
        stiffness = np.asarray(stiffness, dtype=float)
        shape = np.broadcast_shapes(shape, stiffness.shape[:-2])
    T = np.broadcast_to(np.eye(7), shape + (7, 7)).copy()
    T[..., F_IDX, ONE] = -force
    if stiffness is not None:
        T[..., F_IDX[:, None], Z_IDX[None, :]] += stiffness
    return T


def frame_rotation(phi):
    """Frame rotation matrix (Shin Eq. 3.22), shape ``(..., 7, 7)``.

    ``phi = phi_old - phi_new`` [rad] is the counter-clockwise angle from the new frame's x-axis
    to the old frame's x-axis. (u, w) and (N, V) are rotated alike; theta and M are invariant.
    """
    phi = np.asarray(phi, dtype=float)
    c, s = np.cos(phi), np.sin(phi)
    T = np.broadcast_to(np.eye(7), phi.shape + (7, 7)).copy()
    T[..., U, U] = c
    T[..., U, W] = -s
    T[..., W, U] = s
    T[..., W, W] = c
    T[..., N, N] = c
    T[..., N, V] = -s
    T[..., V, N] = s
    T[..., V, V] = c
    return T


def spring_stiffness(k, direction):
    """3x3 local stiffness of a translational spring of stiffness ``k`` [N/m] along ``direction``.

    ``direction`` [rad] is the spring axis measured counter-clockwise from the local x axis. The
    spring has a *sliding end* (Shin §3.3.4.4): its axis keeps its direction, so the force is
    ``-k (n . d) n`` for a nodal displacement ``d``. Rows/columns: conjugate order / (u, w, theta).
    """
    k = np.asarray(k, dtype=float)
    a = np.asarray(direction, dtype=float)
    n = np.stack([np.cos(a), np.sin(a)], axis=-1)
    K = np.zeros(np.broadcast_shapes(k.shape, a.shape) + (3, 3))
    K[..., :2, :2] = k[..., None, None] * n[..., :, None] * n[..., None, :]
    return K


def spring_matrix(k, direction, preload=0.0):
    """Point matrix of a sliding-end translational spring to ground (Shin Eqs. 3.23-3.26).

    ``preload`` [N] is the spring force along ``+direction`` acting on the node in the
    undeformed (rigid-body) configuration, ``K (L - FL)`` in Shin's notation.
    """
    a = np.asarray(direction, dtype=float)
    F = np.asarray(preload, dtype=float)[..., None] * np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1)
    return point_matrix(F, spring_stiffness(k, direction))


def rigid_element_matrix(length, rotation=0.0):
    """Field matrix of a rigid element of length L [m] along local x (Shin Eq. 3.20).

    ``rotation`` [rad] is the element's rotation from the previous iteration (theta-hat). The
    exact secant form is used: ``u1 = u0 - L (1 - cos r)/r * theta``,
    ``w1 = w0 + L sin(r)/r * theta``, so that at convergence (theta = r) the end moves by the
    exact rigid rotation. It replaces Shin's printed sign factor delta, which makes w
    independent of the sign of theta. The moment arm is the rotated element.
    """
    L = np.asarray(length, dtype=float)
    r = np.asarray(rotation, dtype=float)
    T = _empty(L, r)
    small = np.abs(r) < 1e-6
    rr = np.where(small, 1.0, r)
    secant_u = np.where(small, r / 2.0 - r**3 / 24.0, (1.0 - np.cos(rr)) / rr)
    secant_w = np.where(small, 1.0 - r**2 / 6.0, np.sin(rr) / rr)
    T[..., :, :] = np.eye(7)
    T[..., U, TH] = -L * secant_u
    T[..., W, TH] = L * secant_w
    T[..., M, V] = -L * np.cos(r)
    T[..., M, N] = L * np.sin(r)
    return T


def split_blocks(T):
    """Split ``(..., 7, 7)`` into ``T11, T12, T21, T22, t1, t2`` on z = (u, w, theta), f = (N, V, M)."""
    Tz = T[..., Z_IDX, :]
    Tf = T[..., F_IDX, :]
    return (Tz[..., Z_IDX], Tz[..., F_IDX], Tf[..., Z_IDX], Tf[..., F_IDX],
            Tz[..., ONE], Tf[..., ONE])
