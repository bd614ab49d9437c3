"""The implicit integrators of the compiled steps (numba): every integrator of
:mod:`tmm_core.integrators` as linear maps of its state arrays, and the two kernels that apply
them (the history before a step, the update after it).

The integrators are linear and act on every degree of freedom alike, so each is fully described
by a few scalar coefficients per state array (:func:`tmm_core.integrators.linear_maps`), read
off the numpy integrator itself by evaluating its ``history`` and ``advance`` on unit states. No integrator
formula is written here: the numpy classes are the one place that defines them, and the
compiled march and the periodic solver's linearized revolutions both step through
:func:`history` and :func:`advance` on those coefficients.

States are stacked as ``S (K, L)``: the integrator's K state arrays (in the order of its
``initial`` keys), each flattened to L values (n_dof for a march; n_dof times the unit states for
a monodromy, a C-ordered ``(K, n_dof, M)`` array reshaped): the maps act on every value alike, so
each is one contiguous loop.

Owns: the compiled application of the integrators' linear maps. Boundaries: the formulas are
tmm_core.integrators'; compiled and bound by tmm_core.compiled.binding.
"""
from __future__ import annotations


def history(Hc, S, h_a, h_v):
    """The integrator history ``h_a, h_v`` (L,) of the states ``S`` (K, L): the acceleration and
    velocity are ``a = c_a z + h_a``, ``v = c_v z + h_v`` in the step's new displacements ``z``
    (:meth:`tmm_core.integrators.Newmark.history` and its peers)."""
    K, L = S.shape
    for i in range(L):
        h_a[i] = 0.0
        h_v[i] = 0.0
    for q in range(K):
        ca, cv = Hc[0, q], Hc[1, q]
        if ca != 0.0:
            for i in range(L):
                h_a[i] += ca * S[q, i]
        if cv != 0.0:
            for i in range(L):
                h_v[i] += cv * S[q, i]


def advance(Gc, ez, S, z, Snew):
    """The integrator update of the states ``S`` (K, L) in place to the new displacements ``z``
    (L,); ``Snew`` is scratch of the shape of ``S``."""
    K, L = S.shape
    for p in range(K):
        for i in range(L):
            Snew[p, i] = ez[p] * z[i]
        for q in range(K):
            c = Gc[p, q]
            if c != 0.0:
                for i in range(L):
                    Snew[p, i] += c * S[q, i]
    for p in range(K):
        for i in range(L):
            S[p, i] = Snew[p, i]
