"""The frozen discretization of a linkage for the time domain: built once from a mechanism,
never changed after, handed to the stage functions.

A :class:`Discretization` holds what every stage reads of the model: the node layout (DOFs per
link), the lumped masses and damping per DOF, the segment operators (stiffness blocks, gather,
viscoelastic moduli), the gauges and the layout of a step's output row, the integrator, the
rotating-frame coupling, the axial-force model and its tolerances, the backend and the memory
budget of the step data. :func:`discretize` builds it (and checks the settings); the stages take
it as their first argument: the configurations (:func:`tmm_core.batches.configurations`), the
step loads and one step (:mod:`tmm_core.time_step`), the march (:mod:`tmm_core.march`), the
periodic revolution and monodromy (:mod:`tmm_core.periodic`) and the reduced model
(:mod:`tmm_core.reduced`, :mod:`tmm_core.reduced_stages`, :mod:`tmm_core.reduced_periodic`).
:class:`tmm_core.TimeDomain` is the public facade that builds one and delegates to the stages.

Owns: the model record, its building and validation, and the pure views of it (stacking node
vectors, the step's modulus factors, the compiled kernels' model record). Boundaries: nothing
that depends on a crank state (configuration batches are :mod:`tmm_core.batches`'), no mutable
state: caches of a run live in the facade or in the batches.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping, Protocol, Sequence

import numpy as np
import scipy.sparse as sp

from .backend import choose_backend
from .compiled import statics as compiled_statics
from .configuration_batch import OutputLayout
from .errors import InputError, require_positive
from .integrators import get_integrator
from .ked import Coupling, node_mass_arrays
from .matrices import field_matrix
from .mechanism import FourBarMechanism
from .post import Gauge, segment_at
from .riccati import segment_stiffness
from .second_order import Segments

AXIAL_FORCE_MODELS = ("dynamic", "quasi_static", "none")
#: The 'dynamic' step's nonlinear terms: the shortening from bending and the step's own axial
#: force. Alone, they make the second-order (von Karman) segments.
DYNAMIC_TERMS = ("shortening", "axial_force")
#: Optional terms of the 'dynamic' step beyond DYNAMIC_TERMS, at most one of them, each replacing
#: the second-order strain of the segments: 'corotational', segments exact in their rotation (the
#: cubic beam in a frame turning with each segment's chord; every realisation of the step has it;
#: the default); 'exact_strain', the segments' geometrically exact axial strain alone (a prototype
#: that made the agreement worse; numpy step only: a model asking for it runs the numpy backend).
OPTIONAL_TERMS = ("exact_strain", "corotational")
#: The default terms: co-rotational segments. The second-order ones part from geometrically exact
#: beams once a link's segments turn more than about 5 deg against its chord, by several per cent
#: near a resonance and at light damping and by tens of per cent near a fold of the steady response
#: (docs/light_damping.md).
DEFAULT_TERMS = DYNAMIC_TERMS + ("corotational",)
#: The optional terms the compiled march carries.
COMPILED_TERMS = ("corotational",)
#: The strain measure of the second-order pseudo-loads (tmm_core.second_order.STRAIN_MEASURES)
#: each optional term asks for.
_STRAIN_OF_TERM = {"exact_strain": "exact", "corotational": "corotational"}
#: Default memory budget of a batch's maps or stored factorizations [bytes] (``max_map_bytes``).
MAX_STEP_DATA_BYTES = 1e9


@dataclass(frozen=True, eq=False)
class Discretization:
    """The time-domain model of a mechanism, built once by :func:`discretize` and never changed.

    Settings: ``mech`` (the mechanism), ``backend`` ('compiled' or 'numpy', for every stage),
    ``integrator`` (:mod:`tmm_core.integrators`), ``coupling`` (:class:`tmm_core.Coupling`),
    ``beam_column``, ``axial_force`` ('dynamic', 'quasi_static' or 'none'), ``axial_tolerance``
    (relative) and ``axial_iterations`` of the 'dynamic' step, ``dynamic_terms`` (the
    second-order terms it carries), ``gravity`` [m/s^2] (or None), ``max_map_bytes`` [bytes].

    Layout: ``structure`` (the instantaneous structure), ``links`` (the elastic links, in node
    order), ``offsets`` (first DOF of each link), ``n_dof``, ``node_blocks`` (``(link, offset,
    node count)`` per link), ``is_u``/``is_w`` (which DOFs are axial / transverse).

    Masses and damping per DOF: ``m_vec`` [kg, kg m^2], ``aM_vec`` (mass-proportional damping
    [1/s]), ``beta_node`` (stiffness-proportional damping [s]) and ``has_kv`` (any of it).

    Segment operators: ``segments`` (:class:`tmm_core.second_order.Segments`), ``n_seg``,
    ``seg_blocks`` (n_seg, 6, 6) stiffness blocks [N/m, N, N m], ``seg_E1`` (Maxwell modulus over
    the reference modulus per block entry, 0 for elastic segments), the sparse ``gather`` (6
    n_seg, n_dof) of segment end displacements, ``seg_K`` (their block-diagonal stiffness) and
    ``K_local`` (n_dof, n_dof) (the members' stiffness in local frames, no joint coupling).

    Outputs: ``gauges``, ``outputs`` (:class:`tmm_core.configuration_batch.OutputLayout`),
    where each gauge reads its axial strain: ``gauge_segments`` (G, 2) stacked segments and
    ``gauge_weights`` (G, 2) their weights (:func:`axial_sampling`), and where it reads the
    co-rotational segments' bending: ``gauge_bending_segments`` (G,) the stacked segment and
    ``gauge_bending_weights`` (G,) [-] its bending strain per radian of that segment's chord lag
    (:func:`bending_sampling`).

    The arrays the compiled kernels read (masses, damping, segments, blocks, gauge segments) stay
    writeable: numba types a read-only array apart and would compile every kernel a second time
    for it. No stage writes them."""

    mech: FourBarMechanism
    backend: str
    integrator: Any
    coupling: Coupling
    beam_column: bool
    axial_force: str
    axial_tolerance: float
    axial_iterations: int
    dynamic_terms: tuple
    gravity: np.ndarray | None
    max_map_bytes: float
    structure: Any
    links: tuple
    offsets: Mapping[str, int]
    n_dof: int
    node_blocks: tuple
    is_u: np.ndarray
    is_w: np.ndarray
    m_vec: np.ndarray
    aM_vec: np.ndarray
    beta_node: np.ndarray
    has_kv: bool
    segments: Segments
    n_seg: int
    seg_blocks: np.ndarray
    seg_E1: np.ndarray
    gather: Any
    seg_K: Any
    K_local: Any
    gauges: tuple
    outputs: OutputLayout
    gauge_segments: np.ndarray
    gauge_weights: np.ndarray
    gauge_bending_segments: np.ndarray
    gauge_bending_weights: np.ndarray

    def __getstate__(self):
        # A mapping proxy does not pickle (a model crosses process boundaries with its engine):
        # the offsets travel as a plain dict and are wrapped again on arrival.
        state = dict(self.__dict__)
        state["offsets"] = dict(self.offsets)
        return state

    def __setstate__(self, state):
        for name, value in state.items():
            object.__setattr__(self, name, MappingProxyType(value) if name == "offsets" else value)

    @property
    def compiled(self) -> bool:
        """Whether the stages run the compiled kernels (the backend, as a flag)."""
        return self.backend == "compiled"

    @property
    def compiled_factorization(self) -> bool:
        """Build the configurations' load-to-response maps in the compiled factorization
        (:mod:`tmm_core.compiled.structure`): with ``compiled``, for a structure of joints and members
        whose members are the elastic links in order."""
        if not self.compiled or not compiled_statics.supported(self.structure):
            return False
        return [m.name for m in self.structure.members] == [l.name for l in self.links] and \
            all(m.n_segments + 1 == l.n_nodes for m, l in zip(self.structure.members, self.links))

    def stack(self, per_link):
        """Stack per-link arrays ``{link: (..., n+1, 3)}`` into the node vector ``(..., n_dof)``."""
        return np.concatenate([per_link[l.name].reshape(per_link[l.name].shape[:-2] + (-1,)) for l in self.links], -1)

    def unstack(self, vectors: np.ndarray):
        """Split node vectors ``(..., n_dof)`` into ``{link: (..., n_nodes, 3)}``."""
        out = {}
        for name, off, n1 in self.node_blocks:
            out[name] = vectors[..., off:off + 3 * n1].reshape(vectors.shape[:-1] + (n1, 3))
        return out

    def link_factor(self, c_v: float, dt: float):
        """Effective-modulus factor of every segment ``{link: (n,)}`` for the integrator's velocity
        coefficient ``c_v`` [1/s] and step ``dt`` [s] and, per viscoelastic link, the step
        coefficients ``(decay, g)`` of its span."""
        factors, visco = {}, {}
        for link in self.links:
            f = np.full(link.total_segments, 1.0 + link.damping.stiffness_s * c_v)
            if link.viscoelastic is not None:
                sls = link.viscoelastic
                decay, g = sls.step_coefficients(dt)
                f[link.flexible] = ((sls.relaxed_modulus_Pa + g * sls.maxwell_modulus_Pa) / link.material.E_Pa
                                    + link.damping.stiffness_s * c_v)
                visco[link.name] = (decay, g)
            factors[link.name] = f
        return factors, visco

    @property
    def strain_measure(self) -> str:
        """The segments' strain measure of the 'dynamic' step's pseudo-loads
        (:data:`tmm_core.second_order.STRAIN_MEASURES`): from the optional term asked for, else
        'second_order' with the shortening and 'none' without it."""
        for term, strain in _STRAIN_OF_TERM.items():
            if term in self.dynamic_terms:
                return strain
        return "second_order" if "shortening" in self.dynamic_terms else "none"

    def kernel_model(self) -> tuple:
        """The model record the compiled steps read (:func:`tmm_core.compiled.march.march`,
        :func:`tmm_core.compiled.periodic.push`): ``(m, aM, beta_node, seg_start, seg_end, seg_L,
        seg_EA, seg_beta, seg_K, gauge_reading)``: lumped masses [kg, kg m^2] and mass damping per
        DOF, stiffness damping per node, each segment's end nodes, length [m], EA [N], stiffness
        damping [s] and 4x4 bending blocks, and :meth:`gauge_reading`."""
        seg = self.segments
        return (self.m_vec, self.aM_vec, self.beta_node, seg.start, seg.end, seg.length, seg.EA, seg.beta,
                self.seg_blocks, self.gauge_reading())

    def gauge_reading(self) -> tuple:
        """The record of the gauges' sampling the compiled kernels read (the march and the reduced
        revolution): ``(gauge_segments, shortening, bending_segments, bending)``, the two stacked
        segments each gauge's axial strain reads (G, 2) and the weights [1/m] of their shortenings
        in it (:meth:`gauge_shortening_weights`), and the segment whose chord lag moves its bending
        strain (G,) with the weight [-] (:meth:`gauge_lag_strain`)."""
        return self.gauge_segments, self.gauge_shortening_weights(), self.gauge_bending_segments, \
            self.gauge_bending_weights

    def gauge_shortening_weights(self) -> np.ndarray:
        """(G, 2) [1/m]: each gauge's axial strain gains ``sum_c w[g, c] Delta[s[g, c]]`` from the
        shortening ``Delta`` [m] of its two segments ``s`` (:func:`axial_sampling`'s weights over
        the segments' lengths)."""
        return self.gauge_weights / self.segments.length[self.gauge_segments]

    def gauge_shortening_strain(self, delta: np.ndarray) -> np.ndarray:
        """(G,) [-]: the part of each gauge's axial strain that the segments' shortenings from
        bending ``delta`` (S,) [m] make (:meth:`gauge_shortening_weights`)."""
        return np.sum(self.gauge_shortening_weights() * delta[self.gauge_segments], axis=-1)

    def gauge_lag_strain(self, lag: np.ndarray) -> np.ndarray:
        """(G,) [-]: what the co-rotational segments add to each gauge's bending strain, from the
        segments' chord lags ``lag`` (S,) [rad] (:func:`tmm_core.second_order.chord_lag`;
        :func:`bending_sampling`)."""
        return self.gauge_bending_weights * lag[self.gauge_bending_segments]

    def gauge_axial_sampling(self, k: int) -> tuple:
        """``(segments, weights)`` of gauge ``k`` with the segments numbered within its link, as
        :func:`tmm_core.post.gauge_strains` takes them."""
        first = sum(l.total_segments for l in self.links[:[l.name for l in self.links].index(self.gauges[k].link)])
        return tuple(int(s) - first for s in self.gauge_segments[k]), tuple(float(w) for w in self.gauge_weights[k])


class HoldsModel(Protocol):
    """Anything that holds a :class:`Discretization` as ``model`` (the :class:`tmm_core.TimeDomain`
    facade): the public stage entry points accept it and take its model."""

    model: Discretization


def as_model(source: Discretization | HoldsModel) -> Discretization:
    """The :class:`Discretization` of ``source``: itself, or the one it holds (a facade)."""
    return source if isinstance(source, Discretization) else source.model


def discretize(mech: FourBarMechanism, *, integrator: str = "newmark", coupling: Coupling = Coupling(),
               beam_column: bool = True, gravity=None, gauges: Sequence[Gauge] = (),
               max_map_bytes: float = MAX_STEP_DATA_BYTES, axial_force: str = "dynamic", axial_tolerance: float = 1e-8,
               axial_iterations: int = 60, dynamic_terms: tuple = DEFAULT_TERMS,
               backend: str | None = None) -> Discretization:
    """Build the :class:`Discretization` of ``mech`` once; the settings are those of
    :class:`tmm_core.TimeDomain` (documented there), checked here."""
    backend = _backend(dynamic_terms, backend)
    axial_force = _axial_force(axial_force, beam_column)
    links = tuple(mech.elastic_links())
    for g in gauges:
        if g.link not in {l.name for l in links}:
            raise InputError(f"gauge '{g.name}': unknown or rigid link '{g.link}' (a rigid link has no strain)")
    if axial_force == "dynamic" and any(l.viscoelastic is not None for l in links):
        raise InputError("axial_force 'dynamic' is not available with viscoelastic (standard-linear-solid) links; "
                         "use 'quasi_static'")
    # Node layout: every link's nodes, local (u, w, theta), concatenated.
    offsets, off = {}, 0
    for link in links:
        offsets[link.name] = off
        off += 3 * link.n_nodes
    n_dof = off
    masses = node_mass_arrays(mech)
    m_vec = np.concatenate([np.repeat(masses[l.name][0], 3) * np.tile([1.0, 1.0, 0.0], l.n_nodes)
                            + np.repeat(masses[l.name][1], 3) * np.tile([0.0, 0.0, 1.0], l.n_nodes) for l in links])
    beta_node = np.concatenate([np.full(3 * l.n_nodes, l.damping.stiffness_s) for l in links])
    operators = _segment_operators(links, offsets, n_dof)
    return Discretization(
        mech=mech, backend=backend, integrator=get_integrator(integrator), coupling=coupling,
        beam_column=beam_column, axial_force=axial_force,
        axial_tolerance=float(require_positive("axial_tolerance", axial_tolerance)),
        axial_iterations=int(axial_iterations), dynamic_terms=tuple(dynamic_terms),
        gravity=None if gravity is None else _frozen(np.array(gravity, dtype=float)),
        max_map_bytes=max_map_bytes, structure=mech.structure(), links=links, offsets=MappingProxyType(offsets),
        n_dof=n_dof, node_blocks=tuple((l.name, offsets[l.name], l.n_nodes) for l in links),
        is_u=_frozen(np.tile([True, False, False], n_dof // 3)),
        is_w=_frozen(np.tile([False, True, False], n_dof // 3)),
        m_vec=m_vec, aM_vec=np.concatenate([np.full(3 * l.n_nodes, l.damping.mass_per_s) for l in links]),
        beta_node=beta_node, has_kv=bool(np.any(beta_node > 0)), segments=_segments(links, offsets), **operators,
        gauges=tuple(gauges), outputs=OutputLayout.of(tuple(gauges)), **_gauge_sampling(links, gauges))


def _backend(dynamic_terms, backend):
    """The backend of a model asking for ``dynamic_terms``, after checking them."""
    if not set(dynamic_terms) <= set(DYNAMIC_TERMS + OPTIONAL_TERMS):
        raise InputError(f"dynamic_terms must be a subset of {DYNAMIC_TERMS + OPTIONAL_TERMS}, got {dynamic_terms!r}")
    optional = [t for t in OPTIONAL_TERMS if t in dynamic_terms]
    if len(optional) > 1:
        raise InputError(f"dynamic_terms: give at most one of {OPTIONAL_TERMS}, got {dynamic_terms!r}")
    if optional:
        term = optional[0]
        if not set(DYNAMIC_TERMS) <= set(dynamic_terms):
            raise InputError(f"dynamic_terms: {term!r} replaces the second-order strain of both terms; give it "
                             f"with {DYNAMIC_TERMS}")
        if term in COMPILED_TERMS:
            return choose_backend(backend)
        # A prototype of the numpy step only (the compiled march does not have it): the
        # default backend becomes numpy, an explicit compiled one is refused.
        if backend == "compiled":
            raise InputError(f"dynamic_terms: {term!r} runs in the numpy step only; build the model with "
                             "backend = 'numpy' (or leave the backend to its default)")
        backend = "numpy"
    return choose_backend(backend)


def _axial_force(axial_force, beam_column):
    """The axial-force model after checking it: 'none' without the beam-column coupling."""
    if axial_force == "iterated":
        raise InputError("axial_force 'iterated' was replaced by 'dynamic' (the step's own axial force together "
                         "with the axial shortening from bending; the axial force alone was measured to be worse)")
    if axial_force not in AXIAL_FORCE_MODELS:
        raise InputError(f"axial_force must be one of {AXIAL_FORCE_MODELS}, got {axial_force!r}")
    return "none" if not beam_column else axial_force


def _segment_operators(links, offsets, n_dof) -> dict:
    """Segment stiffness blocks, viscoelastic moduli and the sparse operators built from them
    (built at once: scipy.sparse is loaded with tmm_core anyway, and they cost ~1 ms)."""
    rows, blocks, visco_E1 = [], [], []
    for link in links:
        m = link.member("s", "e")
        K, _ = segment_stiffness(field_matrix(np.asarray(m.segment_lengths), m.EA, m.EI))
        off = offsets[link.name]
        for j in range(link.total_segments):
            rows.append(off + 3 * j + np.arange(6))
            blocks.append(K[j])
            sls = link.viscoelastic if link.flexible[j] else None
            visco_E1.append(0.0 if sls is None else sls.maxwell_modulus_Pa / link.material.E_Pa)
    cols = np.concatenate(rows)
    seg_blocks = np.ascontiguousarray(np.array(blocks))     # (n_seg, 6, 6), for the compiled step
    gather = sp.csr_matrix((np.ones(len(cols)), (np.arange(len(cols)), cols)), shape=(len(cols), n_dof))
    seg_K = sp.block_diag(list(seg_blocks), format="csr")
    # Maxwell modulus / reference modulus per segment entry (0 for elastic segments).
    return {"n_seg": len(blocks), "seg_blocks": seg_blocks, "seg_E1": _frozen(np.repeat(np.array(visco_E1), 6)),
            "gather": gather, "seg_K": seg_K, "K_local": (gather.T @ seg_K @ gather).tocsr()}


def _segments(links, offsets) -> Segments:
    """Segment data of the node vector (second-order terms, axial forces)."""
    starts, lengths, EA, beta, EI = [], [], [], [], []
    for link in links:
        m = link.member("s", "e")
        starts.append(offsets[link.name] + 3 * np.arange(link.total_segments))
        lengths.append(np.asarray(m.segment_lengths))
        EA.append(m.EA)
        EI.append(m.EI)
        beta.append(np.full(link.total_segments, link.damping.stiffness_s))
    starts = np.concatenate(starts)
    return Segments(starts, starts + 3, np.concatenate(lengths), np.concatenate(EA), np.concatenate(beta),
                    np.concatenate(EI))


def axial_sampling(link, position: float) -> tuple:
    """``((j, k), (w_j, w_k))``: the segments of ``link`` (numbered from its start) whose axial
    strains give the axial strain at ``position`` [m], and their weights.

    Why two: the time step lumps every mass on the nodes, so a segment's axial force is constant
    along it, and it is the continuous force at the segment's middle (the mass of each half
    segment sits on the node beside it). At a node, the segment after it is half a segment off: on
    a link whose axial force falls along it, the gauge read the force there 1/(2 n) of the link
    too low (a slider-crank's coupler at 8 segments: 2.5 % low, converging as 1/n). So the strain
    is interpolated linearly between the middles of the gauge's segment ``j`` and its neighbour
    ``k`` on the gauge's side (at a node between equal segments: their mean). Not across a
    change of section or material, an end block, or a node that carries a point mass, where the
    force jumps: there the gauge's own segment alone, ``(j, j), (1, 0)``."""
    x = link.stations
    n = link.total_segments
    j = segment_at(x, position)
    middle = 0.5 * (x[:-1] + x[1:])
    k = j + 1 if position >= middle[j] else j - 1
    if not 0 <= k < n or not _same_segments(link, j, k):
        return (j, j), (1.0, 0.0)
    w = float((position - middle[j]) / (middle[k] - middle[j]))
    return (j, k), (1.0 - w, w)


def _same_segments(link, j: int, k: int) -> bool:
    """Whether the axial strain is continuous between segments ``j`` and ``k`` of ``link``
    (neighbours): both flexible, of one section and material, and no point mass on their node."""
    member, flexible = link.member("s", "e"), link.flexible
    sections, materials = member.sections, member.materials
    node = link.stations[max(j, k)]
    on_node = any(abs(p.position_m - node) <= 1e-9 * link.length_m for p in link.point_masses)
    return bool(flexible[j] and flexible[k] and sections[j] == sections[k] and materials[j] == materials[k]
                and not on_node)


def bending_sampling(link, gauge: Gauge) -> tuple:
    """``(j, weight)``: the segment of ``link`` (numbered from its start) whose bending ``gauge``
    reads (:func:`tmm_core.post.gauge_strains`: the one starting at or before it), and the
    gauge's bending strain per radian of that segment's chord lag [-].

    Why: the solver's bending moment is that of the linear segment, whose end rotations against
    the chord are ``theta_i - dw/L``; a co-rotational segment's are ``theta_i - b`` with ``b`` the
    chord's exact angle. Their difference, the chord lag ``psi = dw/L - b``
    (:func:`tmm_core.second_order.chord_lag`), is the same at both ends, so the co-rotational
    cubic's curvature at ``xi = x/L`` exceeds the linear one by ``(12 xi - 6) psi / L``. The
    pseudo-loads carry that difference as node moments, and the solver's moment inside a segment
    does not see them. It grows as 1/L: small on a slender link, it moved a node gauge on thick
    bars with the mesh (docs/light_damping.md)."""
    x = link.stations
    j = segment_at(x, gauge.position_m)
    length = float(x[j + 1] - x[j])
    xi = (gauge.position_m - x[j]) / length
    sign = -1.0 if gauge.face == "top" else 1.0      # as gauge_strains: sigma = N/A - M y / I
    depth = link.member("s", "e").sections[j].depth_m
    return j, sign * 0.5 * depth * (12.0 * xi - 6.0) / length


def _gauge_sampling(links, gauges) -> dict:
    """The ``gauge_segments`` (G, 2, stacked) and ``gauge_weights`` (G, 2) of a model
    (:func:`axial_sampling` per gauge), and its ``gauge_bending_segments`` (G,) and
    ``gauge_bending_weights`` (G,) (:func:`bending_sampling`)."""
    first = dict(zip([l.name for l in links], np.cumsum([0] + [l.total_segments for l in links])))
    segments, weights, bending = [], [], []
    for g in gauges:
        link = next(l for l in links if l.name == g.link)
        (j, k), w = axial_sampling(link, g.position_m)
        segments.append((first[link.name] + j, first[link.name] + k))
        weights.append(w)
        b, wb = bending_sampling(link, g)
        bending.append((first[link.name] + b, wb))
    return {"gauge_segments": np.array(segments, dtype=np.int64).reshape(-1, 2),
            "gauge_weights": np.array(weights, dtype=float).reshape(-1, 2),
            "gauge_bending_segments": np.array([b for b, _ in bending], dtype=np.int64),
            "gauge_bending_weights": np.array([w for _, w in bending], dtype=float)}


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (a model's arrays that no kernel reads)."""
    array.flags.writeable = False
    return array
