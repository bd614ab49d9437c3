"""The factorization phase of the compiled solve (:func:`tmm_core.compiled.structure.solve_range`) for
one configuration: the Riccati condensation of every member (:func:`tmm_core.riccati.factor_chain`),
the assembled joint system, its inertia and pivots (LDL^T) and its LU factors. Compiled by
:func:`tmm_core.compiled.binding.static_solve`.

Owns: the factorization phase of one configuration in the compiled kernel. Boundaries: no loads
(tmm_core.compiled.structure.solve_loads).
"""
from __future__ import annotations

import math

import numpy as np

from .dense import full6, inv3, ldl_inertia, lu_factor, mm3, segment_blocks


def factor_scratch(nf):
    """The scratch record of :func:`factor_configuration` (``nf`` free joint DOFs): ``(Kc, T6, t6,
    tmp6, Kff, Ks, work, c5, sp, T11, T12, T21, T22, A, Bm, C, D, t1, t2, zi, fi)``, the last two
    the index vectors of the state's displacement and force rows."""
    return (np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(6), np.zeros((6, 6)), np.zeros((nf, nf)), np.zeros((nf, nf)),
            np.zeros((max(nf, 3), max(nf, 3))), np.zeros(5), np.zeros(10), np.zeros((3, 3)), np.zeros((3, 3)),
            np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)),
            np.zeros(3), np.zeros(3), np.array([0, 1, 2]), np.array([5, 4, 3]))


def factor_configuration(bi, segments, configuration, joints, checks, factors, scratch):
    """Factorize configuration ``bi`` into the per-configuration ``factors`` record (load-independent
    member factors, joint stiffness ``Kfull``, LU factors ``lu``, ``piv``) and set its ``status``,
    ``negative`` and ``pivots`` entries. False if the joint system is singular.

    Records (tuples of arrays, unpacked below; names and units as
    :func:`tmm_core.compiled.structure.solve_range`): ``segments = (inv_fact, seg_off, L, EA, EI,
    rigid)``, ``configuration = (factor, P, qloc, Kn, angle)`` (batch axis first), ``joints =
    (ends, free, count)``, ``checks = (negative, pivots, status)``, ``factors`` as
    :data:`tmm_core.compiled.time_step.STORED` for one configuration, ``scratch`` from
    :func:`factor_scratch`."""
    inv_fact, seg_off, L, EA, EI, rigid = segments
    factor, P, qloc, Kn, angle = configuration
    ends, free, count = joints
    negative, pivots, status = checks
    lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv = factors
    Kc, T6, t6, tmp6, Kff, Ks, work, c5, sp, T11, T12, T21, T22, A, Bm, C, D, t1, t2, zi, fi = scratch
    M, nd, nf = seg_off.shape[0] - 1, Kfull.shape[0], lu.shape[0]
    status[bi] = 0
    neg_chain = 0
    for i in range(nd):
        for j in range(nd):
            Kfull[i, j] = 0.0
    # -- factorization (tmm_core.riccati.factor_chain), member by member -----------------
    for mi in range(M):
        s0, s1 = seg_off[mi], seg_off[mi + 1]
        n = s1 - s0
        m = 2 * n + 1
        node0 = s0 + mi
        # The chain: point matrix of node j at index 2j, segment j at 2j + 1; the first
        # deformable segment starts the Riccati recursion, everything before it is a prefix.
        first = -1
        for j in range(n):
            if not rigid[s0 + j]:
                first = 2 * j + 1
                break
        firsts[mi] = first
        for r in range(6):
            for q in range(6):
                prefix[mi, 0, r, q] = 1.0 if r == q else 0.0
        for j in range(first):
            if j % 2 == 0:       # point matrix: identity with the node stiffness in the f-z block
                nd_ = node0 + j // 2
                for r in range(6):
                    for q in range(6):
                        lead[mi, j, r, q] = 1.0 if r == q else 0.0
                for r in range(3):
                    for q in range(3):
                        lead[mi, j, fi[r], zi[q]] += Kn[bi, nd_, r, q]
            else:                # a rigid segment before the first deformable one
                # np.bool_, not a bare True/False: numba compiles a callee once more for every
                # literal argument (here and below: segment_blocks three times instead of once).
                segment_blocks(L[s0 + j // 2], 1.0, 1.0, 0.0, 0.0, 0.0, np.bool_(True), inv_fact, c5, sp, t1, t2)
                full6(sp, t1, t2, T6, t6)
                for r in range(6):
                    for q in range(6):
                        lead[mi, j, r, q] = T6[r, q]
            for r in range(6):
                for q in range(6):
                    acc = 0.0
                    for w in range(6):
                        acc += lead[mi, j, r, w] * prefix[mi, j, w, q]
                    prefix[mi, j + 1, r, q] = acc
        sg = s0 + first // 2
        segment_blocks(L[sg], EA[sg] * factor[bi, sg], EI[sg] * factor[bi, sg], P[bi, sg], qloc[bi, sg, 1],
                        qloc[bi, sg, 0], np.bool_(False), inv_fact, c5, sp, t1, t2)
        full6(sp, t1, t2, T6, t6)
        for r in range(6):
            lcol[mi, r] = t6[r]
            for q in range(6):
                lead[mi, first, r, q] = T6[r, q]
                acc = 0.0
                for w in range(6):
                    acc += T6[r, w] * prefix[mi, first, w, q]
                tmp6[r, q] = acc
        for r in range(3):
            for q in range(3):
                T11[r, q] = tmp6[zi[r], zi[q]]
                T12[r, q] = tmp6[zi[r], fi[q]]
                T21[r, q] = tmp6[fi[r], zi[q]]
                T22[r, q] = tmp6[fi[r], fi[q]]
        det = inv3(T12, Bm)
        if det == 0.0 or not math.isfinite(det):
            status[bi] = 2
        mm3(Bm, T11, A)
        for r in range(3):
            for q in range(3):
                A[r, q] = -A[r, q]
        mm3(T22, A, C)
        for r in range(3):
            for q in range(3):
                C[r, q] += T21[r, q]
        mm3(T22, Bm, D)
        for r in range(3):
            for q in range(3):
                B0[mi, r, q] = Bm[r, q]
                T220[mi, r, q] = T22[r, q]
                Cs[mi, first + 1, r, q] = C[r, q]
                Ds[mi, first + 1, r, q] = D[r, q]
        a00 = A[0, 0]; a01 = A[0, 1]; a02 = A[0, 2]; a10 = A[1, 0]; a11 = A[1, 1]; a12 = A[1, 2]; a20 = A[2, 0]; a21 = A[2, 1]; a22 = A[2, 2]
        b00 = Bm[0, 0]; b01 = Bm[0, 1]; b02 = Bm[0, 2]; b10 = Bm[1, 0]; b11 = Bm[1, 1]; b12 = Bm[1, 2]; b20 = Bm[2, 0]; b21 = Bm[2, 1]; b22 = Bm[2, 2]
        c00 = C[0, 0]; c01 = C[0, 1]; c02 = C[0, 2]; c10 = C[1, 0]; c11 = C[1, 1]; c12 = C[1, 2]; c20 = C[2, 0]; c21 = C[2, 1]; c22 = C[2, 2]
        d00 = D[0, 0]; d01 = D[0, 1]; d02 = D[0, 2]; d10 = D[1, 0]; d11 = D[1, 1]; d12 = D[1, 2]; d20 = D[2, 0]; d21 = D[2, 1]; d22 = D[2, 2]
        for j in range(first + 1, m):
            if j % 2 == 0:
                nd_ = node0 + j // 2
                d00 += Kn[bi, nd_, 0, 0]; d01 += Kn[bi, nd_, 0, 1]; d02 += Kn[bi, nd_, 0, 2]
                d10 += Kn[bi, nd_, 1, 0]; d11 += Kn[bi, nd_, 1, 1]; d12 += Kn[bi, nd_, 1, 2]
                d20 += Kn[bi, nd_, 2, 0]; d21 += Kn[bi, nd_, 2, 1]; d22 += Kn[bi, nd_, 2, 2]
            else:
                sg = s0 + j // 2
                segment_blocks(L[sg], EA[sg] * factor[bi, sg], EI[sg] * factor[bi, sg], P[bi, sg],
                                qloc[bi, sg, 1], qloc[bi, sg, 0], rigid[sg], inv_fact, c5, sp, t1, t2)
                for r in range(10):
                    SP[mi, j // 2, r] = sp[r]
                for r in range(3):
                    TL[mi, j // 2, r] = t1[r]
                    TL[mi, j // 2, r + 3] = t2[r]
                ta, e1, u22, f11, f12, f21, f22, kk, g, v22 = (sp[0], sp[1], sp[2], sp[3], sp[4], sp[5], sp[6],
                                                             sp[7], sp[8], sp[9])
                # G = T11 + T12 D, X = T12 C, H = T21 + T22 D (sparse blocks; scalars: registers, not memory)
                g00 = 1.0 + ta * d00; g01 = ta * d01; g02 = ta * d02
                g10 = f11 * d10 + f12 * d20; g11 = 1.0 + (f11 * d11 + f12 * d21); g12 = e1 + (f11 * d12 + f12 * d22)
                g20 = f21 * d10 + f22 * d20; g21 = f21 * d11 + f22 * d21; g22 = u22 + (f21 * d12 + f22 * d22)
                x00 = ta * c00; x01 = ta * c01; x02 = ta * c02
                x10 = f11 * c10 + f12 * c20; x11 = f11 * c11 + f12 * c21; x12 = f11 * c12 + f12 * c22
                x20 = f21 * c10 + f22 * c20; x21 = f21 * c11 + f22 * c21; x22 = f21 * c12 + f22 * c22
                h00 = d00; h01 = d01; h02 = d02; h10 = d10; h11 = d11; h12 = d12
                h20 = g * d10 + v22 * d20; h21 = g * d11 + v22 * d21; h22 = kk + (g * d12 + v22 * d22)
                i00 = g11 * g22 - g12 * g21; i01 = g02 * g21 - g01 * g22; i02 = g01 * g12 - g02 * g11
                i10 = g12 * g20 - g10 * g22; i11 = g00 * g22 - g02 * g20; i12 = g02 * g10 - g00 * g12
                i20 = g10 * g21 - g11 * g20; i21 = g01 * g20 - g00 * g21; i22 = g00 * g11 - g01 * g10
                det = g00 * i00 + g01 * i10 + g02 * i20
                if det != 0.0 and math.isfinite(det):
                    rdet = 1.0 / det
                    i00 *= rdet; i01 *= rdet; i02 *= rdet; i10 *= rdet; i11 *= rdet; i12 *= rdet
                    i20 *= rdet; i21 *= rdet; i22 *= rdet
                else:
                    status[bi] = 2
                if count[mi] and not rigid[sg]:
                    # The eliminated Schur complement T12^-1 G: its inertia from the LDL^T pivots.
                    rta = 1.0 / ta
                    rd2 = 1.0 / (f11 * f22 - f12 * f21)
                    m00 = g00 * rta; m01 = g01 * rta; m02 = g02 * rta
                    m10 = (f22 * g10 - f12 * g20) * rd2; m11 = (f22 * g11 - f12 * g21) * rd2; m12 = (f22 * g12 - f12 * g22) * rd2
                    m20 = (-f21 * g10 + f11 * g20) * rd2; m21 = (-f21 * g11 + f11 * g21) * rd2; m22 = (-f21 * g12 + f11 * g22) * rd2
                    s00 = m00; s01 = 0.5 * (m01 + m10); s02 = 0.5 * (m02 + m20)
                    s11 = m11; s12 = 0.5 * (m12 + m21); s22 = m22
                    if s00 < 0.0:
                        neg_chain += 1
                    if s00 != 0.0:
                        s11 -= s01 / s00 * s01
                        s12 -= s02 / s00 * s01
                        s22 -= s02 / s00 * s02
                    if s11 < 0.0:
                        neg_chain += 1
                    if s11 != 0.0:
                        s22 -= s12 / s11 * s12
                    if s22 < 0.0:
                        neg_chain += 1
                hg00 = h00 * i00 + h01 * i10 + h02 * i20
                hg01 = h00 * i01 + h01 * i11 + h02 * i21
                hg02 = h00 * i02 + h01 * i12 + h02 * i22
                hg10 = h10 * i00 + h11 * i10 + h12 * i20
                hg11 = h10 * i01 + h11 * i11 + h12 * i21
                hg12 = h10 * i02 + h11 * i12 + h12 * i22
                hg20 = h20 * i00 + h21 * i10 + h22 * i20
                hg21 = h20 * i01 + h21 * i11 + h22 * i21
                hg22 = h20 * i02 + h21 * i12 + h22 * i22
                bg00 = b00 * i00 + b01 * i10 + b02 * i20
                bg01 = b00 * i01 + b01 * i11 + b02 * i21
                bg02 = b00 * i02 + b01 * i12 + b02 * i22
                bg10 = b10 * i00 + b11 * i10 + b12 * i20
                bg11 = b10 * i01 + b11 * i11 + b12 * i21
                bg12 = b10 * i02 + b11 * i12 + b12 * i22
                bg20 = b20 * i00 + b21 * i10 + b22 * i20
                bg21 = b20 * i01 + b21 * i11 + b22 * i21
                bg22 = b20 * i02 + b21 * i12 + b22 * i22
                p00 = bg00 * x00 + bg01 * x10 + bg02 * x20
                p01 = bg00 * x01 + bg01 * x11 + bg02 * x21
                p02 = bg00 * x02 + bg01 * x12 + bg02 * x22
                p10 = bg10 * x00 + bg11 * x10 + bg12 * x20
                p11 = bg10 * x01 + bg11 * x11 + bg12 * x21
                p12 = bg10 * x02 + bg11 * x12 + bg12 * x22
                p20 = bg20 * x00 + bg21 * x10 + bg22 * x20
                p21 = bg20 * x01 + bg21 * x11 + bg22 * x21
                p22 = bg20 * x02 + bg21 * x12 + bg22 * x22
                r00 = hg00 * x00 + hg01 * x10 + hg02 * x20
                r01 = hg00 * x01 + hg01 * x11 + hg02 * x21
                r02 = hg00 * x02 + hg01 * x12 + hg02 * x22
                r10 = hg10 * x00 + hg11 * x10 + hg12 * x20
                r11 = hg10 * x01 + hg11 * x11 + hg12 * x21
                r12 = hg10 * x02 + hg11 * x12 + hg12 * x22
                r20 = hg20 * x00 + hg21 * x10 + hg22 * x20
                r21 = hg20 * x01 + hg21 * x11 + hg22 * x21
                r22 = hg20 * x02 + hg21 * x12 + hg22 * x22
                a00 -= p00; a01 -= p01; a02 -= p02; a10 -= p10; a11 -= p11; a12 -= p12; a20 -= p20; a21 -= p21; a22 -= p22
                c20 = (g * c10 + v22 * c20) - r20; c21 = (g * c11 + v22 * c21) - r21; c22 = (g * c12 + v22 * c22) - r22
                c00 = c00 - r00; c01 = c01 - r01; c02 = c02 - r02; c10 = c10 - r10; c11 = c11 - r11; c12 = c12 - r12
                b00 = bg00; b01 = bg01; b02 = bg02; b10 = bg10; b11 = bg11; b12 = bg12; b20 = bg20; b21 = bg21; b22 = bg22
                d00 = hg00; d01 = hg01; d02 = hg02; d10 = hg10; d11 = hg11; d12 = hg12; d20 = hg20; d21 = hg21; d22 = hg22
                Gis[mi, j // 2, 0, 0] = i00; Gis[mi, j // 2, 0, 1] = i01; Gis[mi, j // 2, 0, 2] = i02
                Gis[mi, j // 2, 1, 0] = i10; Gis[mi, j // 2, 1, 1] = i11; Gis[mi, j // 2, 1, 2] = i12
                Gis[mi, j // 2, 2, 0] = i20; Gis[mi, j // 2, 2, 1] = i21; Gis[mi, j // 2, 2, 2] = i22
                Xs[mi, j // 2, 0, 0] = x00; Xs[mi, j // 2, 0, 1] = x01; Xs[mi, j // 2, 0, 2] = x02
                Xs[mi, j // 2, 1, 0] = x10; Xs[mi, j // 2, 1, 1] = x11; Xs[mi, j // 2, 1, 2] = x12
                Xs[mi, j // 2, 2, 0] = x20; Xs[mi, j // 2, 2, 1] = x21; Xs[mi, j // 2, 2, 2] = x22
                BGis[mi, j // 2, 0, 0] = bg00; BGis[mi, j // 2, 0, 1] = bg01; BGis[mi, j // 2, 0, 2] = bg02
                BGis[mi, j // 2, 1, 0] = bg10; BGis[mi, j // 2, 1, 1] = bg11; BGis[mi, j // 2, 1, 2] = bg12
                BGis[mi, j // 2, 2, 0] = bg20; BGis[mi, j // 2, 2, 1] = bg21; BGis[mi, j // 2, 2, 2] = bg22
                HGis[mi, j // 2, 0, 0] = hg00; HGis[mi, j // 2, 0, 1] = hg01; HGis[mi, j // 2, 0, 2] = hg02
                HGis[mi, j // 2, 1, 0] = hg10; HGis[mi, j // 2, 1, 1] = hg11; HGis[mi, j // 2, 1, 2] = hg12
                HGis[mi, j // 2, 2, 0] = hg20; HGis[mi, j // 2, 2, 1] = hg21; HGis[mi, j // 2, 2, 2] = hg22
            Cs[mi, j + 1, 0, 0] = c00; Cs[mi, j + 1, 0, 1] = c01; Cs[mi, j + 1, 0, 2] = c02
            Cs[mi, j + 1, 1, 0] = c10; Cs[mi, j + 1, 1, 1] = c11; Cs[mi, j + 1, 1, 2] = c12
            Cs[mi, j + 1, 2, 0] = c20; Cs[mi, j + 1, 2, 1] = c21; Cs[mi, j + 1, 2, 2] = c22
            Ds[mi, j + 1, 0, 0] = d00; Ds[mi, j + 1, 0, 1] = d01; Ds[mi, j + 1, 0, 2] = d02
            Ds[mi, j + 1, 1, 0] = d10; Ds[mi, j + 1, 1, 1] = d11; Ds[mi, j + 1, 1, 2] = d12
            Ds[mi, j + 1, 2, 0] = d20; Ds[mi, j + 1, 2, 1] = d21; Ds[mi, j + 1, 2, 2] = d22
        A[0, 0] = a00; A[0, 1] = a01; A[0, 2] = a02
        A[1, 0] = a10; A[1, 1] = a11; A[1, 2] = a12
        A[2, 0] = a20; A[2, 1] = a21; A[2, 2] = a22
        Bm[0, 0] = b00; Bm[0, 1] = b01; Bm[0, 2] = b02
        Bm[1, 0] = b10; Bm[1, 1] = b11; Bm[1, 2] = b12
        Bm[2, 0] = b20; Bm[2, 1] = b21; Bm[2, 2] = b22
        C[0, 0] = c00; C[0, 1] = c01; C[0, 2] = c02
        C[1, 0] = c10; C[1, 1] = c11; C[1, 2] = c12
        C[2, 0] = c20; C[2, 1] = c21; C[2, 2] = c22
        D[0, 0] = d00; D[0, 1] = d01; D[0, 2] = d02
        D[1, 0] = d10; D[1, 1] = d11; D[1, 2] = d12
        D[2, 0] = d20; D[2, 1] = d21; D[2, 2] = d22
        for r in range(3):
            for q in range(3):
                Af[mi, r, q] = A[r, q]
                Bf[mi, r, q] = Bm[r, q]
                Kc[r, q] = -A[r, q]
                Kc[r, q + 3] = -Bm[r, q]
                Kc[r + 3, q] = C[r, q]
                Kc[r + 3, q + 3] = D[r, q]
        # Rotate to the global frame (Lam^T Kc Lam) and add to the joint system.
        cp = math.cos(-angle[bi, mi])
        sn = math.sin(-angle[bi, mi])
        for r in range(6):
            for h in range(2):
                o = 3 * h
                tmp6[r, o] = Kc[r, o] * cp + Kc[r, o + 1] * sn
                tmp6[r, o + 1] = Kc[r, o] * (-sn) + Kc[r, o + 1] * cp
                tmp6[r, o + 2] = Kc[r, o + 2]
        for h in range(2):
            o = 3 * h
            e0, e1_, e2 = ends[mi, o], ends[mi, o + 1], ends[mi, o + 2]
            for q in range(6):
                eq = ends[mi, q]
                Kfull[e0, eq] += cp * tmp6[o, q] + sn * tmp6[o + 1, q]
                Kfull[e1_, eq] += -sn * tmp6[o, q] + cp * tmp6[o + 1, q]
                Kfull[e2, eq] += tmp6[o + 2, q]
    negative[bi, 0] = neg_chain
    # Joint system: inertia and singularity from the LDL^T pivots of the scaled symmetric part.
    for i in range(nf):
        for j in range(nf):
            Kff[i, j] = Kfull[free[i], free[j]]
    for i in range(nf):
        if Kff[i, i] == 0.0:
            status[bi] = 1
    for i in range(nf):
        di = math.sqrt(abs(Kff[i, i])) if Kff[i, i] != 0.0 else 1.0
        for j in range(nf):
            dj = math.sqrt(abs(Kff[j, j])) if Kff[j, j] != 0.0 else 1.0
            Ks[i, j] = 0.5 * (Kff[i, j] + Kff[j, i]) / di / dj
    ng, pmin, pmax = ldl_inertia(Ks, nf, work)
    negative[bi, 1] = ng
    pivots[bi, 0] = pmin
    pivots[bi, 1] = pmax
    for i in range(nf):
        for j in range(nf):
            lu[i, j] = Kff[i, j]
    if not lu_factor(lu, piv):
        status[bi] = 2
        return False
    return True
