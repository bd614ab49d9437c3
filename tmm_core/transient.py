"""Time-domain analysis of a linkage under a prescribed crank motion (transfer-matrix method).

The elastic motion adds inertia ``m (q_ddot + coupling)`` at every lumped mass (:mod:`tmm_core.ked`
gives the mass model and the rotating-frame terms). With an implicit integrator
(:mod:`tmm_core.integrators`) each step is a static solution of the instantaneous structure with a
"dynamic stiffness" ``m c_a`` at each mass and history loads (Shin Eq. 3.47).

Speed: for every distinct crank position the solver factorizes the instantaneous structure once
and stores the dense maps from nodal loads to nodal displacements, drive torque, gauge strains
and segment axial forces (unit loads pushed through the Riccati factorization, batched). A
constant-speed run re-uses the maps of one revolution and marches them in the compiled kernel
(:mod:`tmm_core.compiled.march`); other crank histories are processed in chunks.

Public: :class:`TimeDomain` (``configurations``, ``step_loads``, ``solve_step``, ``begin``,
``run``). Owns the building of the configuration batches (:class:`tmm_core.ConfigurationBatch`:
the factor, the maps and the rigid-body loads of each crank state).
"""
from __future__ import annotations

import functools
import math
from typing import Callable, Mapping, Sequence

import numpy as np

from .compiled import statics as compiled_statics
from .configuration_batch import ConfigurationBatch, CrankStates, OutputLayout
from .backend import choose_backend
from .errors import ConvergenceError, DynamicStabilityError, InputError, require_positive
from .integrators import get_integrator
from .ked import (Coupling, CrankMotion, KEDResult, coupling_stiffness, linear_axial_forces, node_mass_arrays,
                  quasi_static, rigid_body_loads, segment_forces)
from .march import March
from .matrices import field_matrix
from .mechanism import FourBarMechanism
from .post import Gauge
from .riccati import segment_stiffness
from .second_order import Segments
from . import step_data
from .structure import LoadCase, factorize
from .time_step import AXIAL_FORCE_MODELS, DYNAMIC_TERMS, OPTIONAL_TERMS, StepSolver

# The dense load-to-response maps cost O(n_dof^2) per configuration to build (once per revolution
# of a periodic run) and a mat-vec per step to apply; without them every step runs the Riccati load
# sweep, O(n_dof) but ~5 ms of Python per step. Measured (FE crank-rocker, one revolution at 1 deg,
# maps built in chunks vs sweeps): 0.92 / 1.53 s at 81 dof (8 segments per link), 1.42 / 2.42 s at
# 153 dof, 4.9 / 5.1 s at 297 dof (peak 509 MB; 13.2 s and 1.1 GB when built in one batch); each
# further revolution costs the maps almost nothing. So the maps are used up to 32 segments per
# link (and within max_map_bytes); beyond, the sweeps keep the cost linear in the segment count.
MAP_MAX_DOF = 320
# With the compiled factorization the alternative to the maps is the compiled march on the stored
# factorizations (tmm_core.compiled.time_step): a set-up of one factorization per configuration
# instead of n_dof + 1 solves, a step 2-4x dearer at small models and cheaper from ~200 DOFs.
# Measured (set-up of one revolution maps / factors, then per step; 2-core machine): FE rig
# 4 segments per link, 1 deg (30 DOFs) 23 / 8 ms, 2.9 / 11.0 us; Alexander-Lawrence 4 segments
# (45 DOFs) 43 / 11 ms, 6.2 / 16.3 us; FE rig 8 segments, 0.5 deg (54) 55-66 / 15-17 ms,
# 6.9 / 14.4 us; Alexander-Lawrence 8 segments (81) 76 / 14 ms, 14.7 / 25.0 us; FE rig 16
# segments (102) 181 / 19 ms, 16.0 / 23.6 us; Watt six-bar 8 segments (135) 300 / 26 ms,
# 23.8 / 29.5 us; FE rig 32 segments (198) 752 / 35 ms, 46 / 40 us. The maps repay their set-up
# after ~8-9 revolutions at 45-54 DOFs, ~17 at 81, ~30 at 102 and ~130 at 135: built up to 64.
FACTORS_ABOVE_DOF = 64
#: Default memory budget of a batch's maps or stored factorizations [bytes] (``max_map_bytes``).
MAX_STEP_DATA_BYTES = 1e9


class TimeDomain(StepSolver):
    """Time-domain analysis of a four-bar under a prescribed crank motion.

    Parameters
    ----------
    mech : the mechanism (links carry their mass model, damping and viscoelastic law).
    integrator : 'newmark' (average acceleration) or 'houbolt' (Shin).
    coupling : rotating-frame terms, see :class:`Coupling`.
    beam_column : include the axial-force (beam-column) coupling of bending; False is linear
        theory (``axial_force='none'``).
    axial_force : how the axial force enters the bending equations when ``beam_column``:
        'dynamic' (default): second-order beam theory (:mod:`tmm_core.second_order`): the
        step's own axial force, including the axial shortening from bending, iterated within
        every step on the cached factorization; it agrees with geometrically exact beams near
        buckling (FE crank-rocker at 373 rpm, within a few per cent of exudyn where
        'quasi_static' is 8-24 % off). A transient excursion past the static Euler load is
        integrated as long as the dynamic system stays positive definite.
        'quasi_static': the quasi-static (rigid-body) axial force of each crank position, fixed
        in the field matrices; linear per step and cheaper; good far from buckling.
    axial_tolerance, axial_iterations : relative tolerance and iteration limit of the 'dynamic'
        step iteration.
    dynamic_terms : the second-order terms of the 'dynamic' step: 'shortening' (axial shortening
        from bending) and 'axial_force' (the step's own axial force in the bending equations);
        with both, 'exact_strain' replaces their second-order strain by the segments' geometrically
        exact strain (prototype of issue 34: numpy step only, so it runs the 'numpy' backend).
    backend : 'compiled' (the numba kernels of :mod:`tmm_core.compiled`), 'numpy' (the reference)
        or None (compiled where numba is installed): chosen once here, read by every stage
        (:func:`tmm_core.backend.choose_backend`).
    gravity : gravity vector [m/s^2] in the mechanism plane, or None.
    gauges : gauges whose strains are recorded.
    max_map_bytes : memory budget for the stored load-to-response maps or factorizations of a
        batch; above it each step runs the numpy Riccati load sweep instead (same result, slower).
    """

    def __init__(self, mech: FourBarMechanism, *, integrator: str = "newmark", coupling: Coupling = Coupling(),
                 beam_column: bool = True, gravity=None, gauges: Sequence[Gauge] = (),
                 max_map_bytes: float = MAX_STEP_DATA_BYTES, axial_force: str = "dynamic", axial_tolerance: float = 1e-8,
                 axial_iterations: int = 60, dynamic_terms: tuple = DYNAMIC_TERMS, backend: str | None = None):
        self.mech = mech
        if not set(dynamic_terms) <= set(DYNAMIC_TERMS + OPTIONAL_TERMS):
            raise InputError(f"dynamic_terms must be a subset of {DYNAMIC_TERMS + OPTIONAL_TERMS}, got {dynamic_terms!r}")
        if "exact_strain" in dynamic_terms:
            if not set(DYNAMIC_TERMS) <= set(dynamic_terms):
                raise InputError("dynamic_terms: 'exact_strain' replaces the second-order strain of both terms; give it "
                                 f"with {DYNAMIC_TERMS}")
            # A prototype of the numpy step only (the compiled march does not have it): the
            # default backend becomes numpy, an explicit compiled one is refused.
            if backend == "compiled":
                raise InputError("dynamic_terms: 'exact_strain' runs in the numpy step only; build the model with "
                                 "backend = 'numpy' (or leave the backend to its default)")
            backend = "numpy"
        #: 'compiled' or 'numpy', for every stage of this model (tmm_core.backend).
        self.backend = choose_backend(backend)
        #: The second-order terms the 'dynamic' step carries (both by default; one alone is for
        #: the experiment that separates them, scenarios/engines_agree_experiment.py).
        self.dynamic_terms = tuple(dynamic_terms)
        self.integrator = get_integrator(integrator)
        self.coupling = coupling
        self.beam_column = beam_column
        if axial_force == "iterated":
            raise InputError("axial_force 'iterated' was replaced by 'dynamic' (the step's own axial force together "
                             "with the axial shortening from bending; the axial force alone was measured to be worse)")
        if axial_force not in AXIAL_FORCE_MODELS:
            raise InputError(f"axial_force must be one of {AXIAL_FORCE_MODELS}, got {axial_force!r}")
        self.axial_force = "none" if not beam_column else axial_force
        self.axial_tolerance = float(require_positive("axial_tolerance", axial_tolerance))
        self.axial_iterations = int(axial_iterations)
        self.gravity = None if gravity is None else np.asarray(gravity, dtype=float)
        self.gauges = tuple(gauges)
        #: Columns of a step's output row (drive torque, gauge strains).
        self.outputs = OutputLayout.of(self.gauges)
        for g in self.gauges:
            if g.link not in {l.name for l in mech.elastic_links()}:
                raise InputError(f"gauge '{g.name}': unknown or rigid link '{g.link}' (a rigid link has no strain)")
        self.max_map_bytes = max_map_bytes
        self.structure = mech.structure()
        self.links = mech.elastic_links()
        # Node layout: every link's nodes, local (u, w, theta), concatenated.
        self.offsets, off = {}, 0
        for link in self.links:
            self.offsets[link.name] = off
            off += 3 * link.n_nodes
        self.n_dof = off
        # (link, offset, node count) of every link: Link.n_nodes rebuilds the mesh at each call.
        self._node_blocks = tuple((l.name, self.offsets[l.name], l.n_nodes) for l in self.links)
        masses = node_mass_arrays(mech)
        self.m_vec = np.concatenate([np.repeat(masses[l.name][0], 3) * np.tile([1.0, 1.0, 0.0], l.n_nodes)
                                     + np.repeat(masses[l.name][1], 3) * np.tile([0.0, 0.0, 1.0], l.n_nodes)
                                     for l in self.links])
        self.aM_vec = np.concatenate([np.full(3 * l.n_nodes, l.damping.mass_per_s) for l in self.links])
        #: Stiffness-proportional (Kelvin-Voigt) damping coefficient of every node's link [s].
        self.beta_node = np.concatenate([np.full(3 * l.n_nodes, l.damping.stiffness_s) for l in self.links])
        self.has_kv = bool(np.any(self.beta_node > 0))
        self._is_u = np.tile([True, False, False], self.n_dof // 3)
        self._is_w = np.tile([False, True, False], self.n_dof // 3)
        self._build_segment_operators()
        if self.axial_force == "dynamic" and any(l.viscoelastic is not None for l in self.links):
            raise InputError("axial_force 'dynamic' is not available with viscoelastic (standard-linear-solid) links; "
                             "use 'quasi_static'")
        starts, lengths, EA, beta = [], [], [], []
        for link in self.links:
            m = link.member("s", "e")
            starts.append(self.offsets[link.name] + 3 * np.arange(link.total_segments))
            lengths.append(np.asarray(m.segment_lengths))
            EA.append(m.EA)
            beta.append(np.full(link.total_segments, link.damping.stiffness_s))
        starts = np.concatenate(starts)
        #: Segment data of the node vector (second-order terms, axial forces).
        self.segments = Segments(starts, starts + 3, np.concatenate(lengths), np.concatenate(EA), np.concatenate(beta))
        seg_offset = np.cumsum([0] + [l.total_segments for l in self.links])
        #: Stacked segment index of every gauge (the segment whose shortening enters its axial strain).
        self.gauge_segment = np.array([
            seg_offset[[l.name for l in self.links].index(g.link)] + int(np.clip(
                np.searchsorted(l.stations, g.position_m, side="right") - 1, 0, l.total_segments - 1))
            for g in self.gauges for l in self.links if l.name == g.link], dtype=int)

    # -- material history operators -------------------------------------------------------
    def _build_segment_operators(self):
        """Segment stiffness blocks and viscoelastic moduli; sparse operators when first read."""
        rows, blocks, visco_E1 = [], [], []
        for link in self.links:
            m = link.member("s", "e")
            K, _ = segment_stiffness(field_matrix(np.asarray(m.segment_lengths), m.EA, m.EI))
            off = self.offsets[link.name]
            for j in range(link.total_segments):
                rows.append(off + 3 * j + np.arange(6))
                blocks.append(K[j])
                sls = link.viscoelastic if link.flexible[j] else None
                visco_E1.append(0.0 if sls is None else sls.maxwell_modulus_Pa / link.material.E_Pa)
        self.n_seg = len(blocks)
        self._segment_cols = np.concatenate(rows)
        self.seg_blocks = np.ascontiguousarray(np.array(blocks))     # (n_seg, 6, 6), for the compiled step
        # Maxwell modulus / reference modulus per segment entry (0 for elastic segments).
        self.seg_E1 = np.repeat(np.array(visco_E1), 6)

    @functools.cached_property
    def gather(self):
        """Sparse gather (6 n_seg, n_dof) of every segment's end displacements from the node vector."""
        import scipy.sparse as sp          # here: importing it costs 0.2 s that most users never need
        cols = self._segment_cols
        return sp.csr_matrix((np.ones(len(cols)), (np.arange(len(cols)), cols)), shape=(len(cols), self.n_dof))

    @functools.cached_property
    def seg_K(self):
        """Block diagonal (6 n_seg, 6 n_seg) of the segment stiffnesses (sparse)."""
        import scipy.sparse as sp
        return sp.block_diag(list(self.seg_blocks), format="csr")

    @functools.cached_property
    def K_local(self):
        """Material stiffness in local frames (n_dof, n_dof), member by member (no joint coupling)."""
        return (self.gather.T @ self.seg_K @ self.gather).tocsr()

    def link_factor(self, c_v: float, dt: float):
        """Effective-modulus factor of every segment ``{link: (n,)}`` and, per link, the
        viscoelastic step coefficients ``(decay, g)`` of its span."""
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

    # -- per-configuration maps -------------------------------------------------------------
    def configurations(self, angle, speed, accel, dt, maps: bool | str = "auto", axial_force=None):
        """Factorize the instantaneous structures of a batch of crank states and return the
        affine maps from nodal loads (local, stacked) to nodal displacements, drive torque and
        gauge strains (and, for the 'dynamic' axial force, segment axial forces). ``maps``: True,
        "auto" (the maps only for models up to FACTORS_ABOVE_DOF with the compiled factorization,
        MAP_MAX_DOF without), "factors" (the compiled factorizations kept instead of maps:
        :class:`tmm_core.configuration_batch.StepFactors`) or False (the numpy factorization, built
        when a step asks for it). Beyond max_map_bytes neither maps nor factors are kept.
        ``axial_force``: stacked segment forces ``(B, n_seg)`` [N] for the field matrices instead
        of the quasi-static estimate."""
        mech = self.mech
        motion = mech.motion(angle, speed, accel)
        c_a, c_v = self.integrator.coefficients(dt)
        Kn = coupling_stiffness(mech, motion, self.coupling, c_a, c_v)
        factors, _ = self.link_factor(c_v, dt)
        loads_local = rigid_body_loads(mech, motion, self.gravity, frame="local")
        P = None
        if axial_force is not None:
            cuts = np.cumsum([l.total_segments for l in self.links])[:-1]
            P = dict(zip([l.name for l in self.links], np.split(np.asarray(axial_force, dtype=float), cuts, axis=-1)))
        elif self.axial_force == "dynamic" and self.compiled_factorization:
            # The dynamic step iterates from the linear (rigid-body) estimate, which exists beyond
            # the static Euler load too (the linear quasi_static below, its axial forces alone).
            P = linear_axial_forces(mech, motion, self.gravity, loads_local)
        elif self.axial_force != "none":
            # The axial forces only enter the field matrices (1e-8 relative is ample); the
            # quasi-static model uses the beam-column estimate, whose segment forces are the ones
            # in its field matrices.
            qs = quasi_static(mech, angle, speed, accel, beam_column=self.axial_force == "quasi_static",
                              coupling=Coupling(), gravity=self.gravity, tol=1e-8, backend=self.backend)
            P = {k: segment_forces(r) for k, r in qs.solution.members.items()}
        # Batch (B, 1): the second axis carries the unit loads. Gravity acts through the lumped
        # node masses (rigid_body_loads), like every other inertial load.
        B = len(angle)
        n_rows = self.n_dof + self.outputs.size + (len(self.segments.length) if self.axial_force == "dynamic" else 0)
        n_bytes = 8.0 * B * self.n_dof * n_rows
        if maps not in (True, False, "auto", "factors"):
            raise InputError(f"configurations: maps must be True, False, 'auto' or 'factors', got {maps!r}")
        compiled = self.compiled_factorization
        largest = FACTORS_ABOVE_DOF if compiled else MAP_MAX_DOF
        with_maps = (maps is True or (maps == "auto" and self.n_dof <= largest)) and n_bytes <= self.max_map_bytes
        joints_flat = mech.joint_positions(motion)
        joints = {k: v[:, None, :] for k, v in joints_flat.items()}
        case = LoadCase(joints, {}, {}, {k: v[:, None] for k, v in Kn.items()}, frame="local")

        def make_factor():
            return factorize(self.structure, case, None if P is None else {k: v[:, None] for k, v in P.items()},
                             check_buckling=False, stiffness_factor=factors, count_inertia=True)

        prep = None
        if maps is not False and compiled:
            # The maps come from the compiled factorization (tmm_core.compiled.structure); without
            # them ('factors', or too many DOFs or bytes) the compiled factorizations are kept
            # instead (tmm_core.compiled.time_step: linear in the segments), within the same memory
            # budget. The numpy factor is built only if a step asks for it (ConfigurationBatch.factor).
            prep = compiled_statics.prepare(self.structure, LoadCase(joints_flat, {}, {}, Kn, frame="local"),
                                              stiffness_factor=factors)
            if not with_maps and compiled_statics.stored_bytes(prep) > self.max_map_bytes:
                prep = None
        step_factors = None
        drive = mech.drive_torque_terms(motion, self.gravity)
        if prep is not None:
            P_stacked = compiled_statics.stack_segments(prep, P or {})
            if with_maps:
                maps, negative = step_data.compiled_maps(self, prep, P_stacked, drive)
            else:
                step_factors, negative = step_data.compiled_factors(self, prep, P_stacked, drive)
            factor = None
        else:
            factor = make_factor()
            negative = factor.negative_eigenvalues
        indefinite = np.any(np.reshape(negative, (len(angle), -1)) > 0, axis=-1)
        if np.any(indefinite) and (self.axial_force != "dynamic" or axial_force is not None):
            # The axial forces are those the step uses: the step's dynamic system is indefinite.
            raise DynamicStabilityError(
                f"the dynamic system of the time step (stiffness with the axial forces, plus the step's inertia) is "
                f"not positive definite at crank angle {math.degrees(float(angle[np.argmax(indefinite)])):.6g} deg: "
                "the links buckle even with their inertia; the transfer-matrix model cannot continue (a smaller step "
                "adds inertia)")
        P0 = None if P is None else np.concatenate([P[l.name] for l in self.links], axis=-1)
        crank = CrankStates(np.asarray(angle, float), np.asarray(speed, float), np.asarray(accel, float))

        def batch(step_maps):
            # Configurations whose estimated axial forces leave the step indefinite: the dynamic
            # step refactorizes them at its own axial forces.
            return ConfigurationBatch(crank, motion, self.stack(loads_local), drive, P0, indefinite, step_maps,
                                      make_factor, step_factors, {} if factor is None else {"factor": factor})
        if prep is not None:
            return batch(maps if with_maps else None)
        if not with_maps:
            return batch(None)
        return batch(step_data.numpy_maps(self, factor, drive))

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

    # -- marching -----------------------------------------------------------------------------
    def begin(self, dt: float, angle: float, speed: float, acceleration: float = 0.0, *, start: str = "rest",
              initial: Mapping[str, np.ndarray] | None = None):
        """Start an incremental march at a crank state (step ``dt`` [s]); see :class:`March`."""
        return March(self, float(require_positive("time step dt_s", dt)), float(angle), float(speed),
                     float(acceleration), start, initial)

    def run(self, crank: CrankMotion, *, start: str = "rest", steady_tol: float | None = None,
            min_revolutions: int = 2, record_displacements: bool = True,
            callback: Callable[[int, float], bool] | None = None, chunk: int = 720,
            initial: Mapping[str, np.ndarray] | None = None) -> KEDResult:
        """March through the crank history.

        ``start``: 'rest' (zero elastic state, Shin) or 'quasi_static' (elastic state of the
        quasi-static solution at the first positions). ``steady_tol``: stop when the
        revolution-to-revolution change of the drive torque and gauge strains, relative to their
        peak-to-peak, falls below it (needs a constant-speed history); the change is reported.
        ``callback(step, t)`` returning False stops the run early (partial results kept).
        ``initial``: explicit initial state instead of ``start``: ``{'d', 'v', 'a', 'previous'}``
        with stacked local node vectors (see :attr:`offsets`) and ``previous = (d_-1, d_-2)``.
        """
        dt = crank.dt
        n_steps = len(crank.t)
        N = crank.steps_per_revolution()
        if steady_tol is not None:
            require_positive("steady_tol", steady_tol)
            if N is None:
                raise InputError("steady_tol needs a constant-speed crank history with a whole number of steps per "
                                 "revolution")
        march = self.begin(dt, crank.angle[0], crank.speed[0], crank.acceleration[0], start=start, initial=initial)
        outputs = np.full((n_steps, march.n_out), np.nan)
        disp = np.full((n_steps, self.n_dof), np.nan) if record_displacements else None
        outputs[0] = march.out
        if disp is not None:
            disp[0] = march.z

        cfg, cfg_start, cfg_len = None, -1, 0
        steady, change, done = False, float("nan"), n_steps
        k = 1
        while k < n_steps:
            # Configurations are factorized in batches: one revolution when the history is periodic,
            # chunks of consecutive steps otherwise. Steps are marched in blocks that end at a
            # revolution (the steady-state check) or at the end of a chunk; one by one with a callback.
            if N is not None:
                if cfg is None:
                    cfg = self.configurations(crank.angle[:N], crank.speed[:N], crank.acceleration[:N], dt)
                end = min(n_steps, (k // N + 1) * N)
                indices = np.arange(k, end) % N
            else:
                if cfg is None or k >= cfg_start + cfg_len:
                    cfg_start, cfg_len = k, min(chunk, n_steps - k)
                    sl = slice(k, k + cfg_len)
                    cfg = self.configurations(crank.angle[sl], crank.speed[sl], crank.acceleration[sl], dt)
                end = cfg_start + cfg_len
                indices = np.arange(k, end) - cfg_start
            if callback is not None:
                indices, end = indices[:1], k + 1
            zs, outs = march.step_many(cfg, indices, record_z=disp is not None)
            outputs[k:end] = outs
            if disp is not None:
                disp[k:end] = zs
            if not np.all(np.isfinite(outs)):
                bad = k + int(np.argmax(~np.all(np.isfinite(outs), axis=1)))
                raise ConvergenceError(f"time-domain solution became non-finite at step {bad} (t = {crank.t[bad]:.6g} s); "
                                       "the step may be too large for the stiffest mode (reduce the step)")
            k = end
            last = k - 1
            if N is not None and last >= N and k % N == 0 and k // N >= min_revolutions:
                rev = outputs[k - N:k]
                prev = outputs[k - 2 * N:k - N]
                ptp = np.maximum(np.ptp(rev, axis=0), 1e-300)
                change = float(np.max(np.max(np.abs(rev - prev), axis=0) / ptp))
                if steady_tol is not None and change < steady_tol:
                    steady, done = True, k
                    break
            if callback is not None and callback(last, float(crank.t[last])) is False:
                done = k
                break

        sl = slice(0, done)
        gauges = self.outputs.split(outputs[sl])
        displacements = {}
        if disp is not None:
            displacements = self.unstack(disp[sl])
        revs = (crank.angle[done - 1] - crank.angle[0]) / (2 * math.pi)
        return KEDResult(crank.t[sl], crank.angle[sl], crank.speed[sl], crank.acceleration[sl],
                         self.outputs.torque(outputs[sl]),
                         gauges, displacements, steady, change, abs(float(revs)), self.integrator.name,
                         {"dt_s": dt, "steps": done, "steps_per_revolution": N, "start": start,
                          "maps": cfg.maps is not None if cfg else None})

    def unstack(self, vectors: np.ndarray):
        """Split node vectors ``(..., n_dof)`` into ``{link: (..., n_nodes, 3)}``."""
        out = {}
        for name, off, n1 in self._node_blocks:
            out[name] = vectors[..., off:off + 3 * n1].reshape(vectors.shape[:-1] + (n1, 3))
        return out

    def step_loads(self, cfg, idx, h_a, h_v, *, rigid: bool = True, viscous=None):
        """Stacked local nodal loads of a step at configuration ``idx`` of a batch, for the
        integrator history ``h_a, h_v`` (``(n_dof,)``, or ``(M, n_dof)`` for a batch of states):
        the configuration's D'Alembert loads (left out with ``rigid=False``: the state-dependent
        part alone, for linearizations), the inertia history, the Coriolis terms and the
        Kelvin-Voigt history; ``viscous = (q_sls, decay, gain, d)`` adds the standard-linear-solid
        history of a march. The one place that writes a step's loads."""
        m = self.m_vec
        loads = -m * (h_a + self.aM_vec * h_v)
        if rigid:
            loads = loads + cfg.rigid[idx]
        if self.coupling.coriolis:
            w = self._node_omega(cfg, idx)
            # At u rows the w-velocity history of the same node, at w rows the u-velocity one.
            loads = loads + np.where(self._is_u, 2.0 * m * w * np.roll(h_v, -1, axis=-1), 0.0) \
                - np.where(self._is_w, 2.0 * m * w * np.roll(h_v, 1, axis=-1), 0.0)
        if self.has_kv:
            loads = loads - self.beta_node * (self.K_local @ h_v.T).T
        if viscous is not None:
            q_sls, decay, gain, d = viscous
            loads = loads - self.gather.T @ (decay * q_sls - gain * (self.seg_K @ (self.gather @ d)))
        return loads

    def rest_acceleration(self, loads, motion):
        """Accelerations of the lumped masses under ``loads`` (stacked local) with the structure at
        rest and undeformed: each mass alone, except at joints, where all member ends share the
        translation (and, for rigid connections, the rotation); supported DOFs stay at rest."""
        m = self.m_vec
        a = np.divide(loads, m, out=np.zeros_like(loads), where=m > 0)
        structure = self.structure
        for joint in structure.joints:
            ends = []
            for link, member in zip(self.links, structure.members):
                n = link.total_segments
                if member.start == joint.name:
                    ends.append((link, self.offsets[link.name], member.start_connection))
                if member.end == joint.name:
                    ends.append((link, self.offsets[link.name] + 3 * n, member.end_connection))
            F, M_sum = np.zeros(2), 0.0
            for link, i, _ in ends:
                c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
                R = np.array([[c, -s_], [s_, c]])           # local -> global
                F += R @ loads[i:i + 2]
                M_sum += m[i]
            acc = F / M_sum if M_sum > 0 and joint.support == "free" else np.zeros(2)
            rigid = [e for e in ends if e[2] == "rigid"]
            J_sum = sum(m[i + 2] for _, i, _ in rigid)
            Mz = sum(loads[i + 2] for _, i, _ in rigid)
            for link, i, conn in ends:
                c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
                a[i:i + 2] = np.array([[c, s_], [-s_, c]]) @ acc
                if conn == "rigid":
                    a[i + 2] = Mz / J_sum if J_sum > 0 and joint.support != "clamped" else 0.0
        return a

    def _node_omega(self, cfg, idx):
        motion = cfg.motion
        return np.concatenate([np.full(3 * l.n_nodes, float(motion.link(l.name).omega[idx]))
                               for l in self.links])

    def quasi_static_start(self, th, w, a, dt):
        """Elastic state of the quasi-static solution at the first crank positions: ``(d0, v0, a0,
        (d_-1, d_-2), out0)``, ``out0`` the outputs at ``th`` (drive torque [N m], then bending and
        axial strain per gauge), from the same quasi-static batch (one solve of four positions
        instead of a second one for the outputs: ~2 ms of a set-up)."""
        angles = th + np.array([-2.0, -1.0, 0.0, 1.0]) * w * dt
        qs = quasi_static(self.mech, angles, w, a, beam_column=self.beam_column, coupling=Coupling(),
                          gravity=self.gravity, gauges=self.gauges, backend=self.backend)
        z = np.concatenate([qs.solution.members[l.name].state[:, :, 0, :3].reshape(4, -1) for l in self.links], -1)
        d2, d1, d0, dp = z
        v0 = (dp - d1) / (2 * dt)
        a0 = (dp - 2 * d0 + d1) / dt**2
        out0 = np.concatenate([qs.drive_torque[2:3]] + [np.r_[b[2], a[2]] for b, a in qs.gauges.values()])
        return d0, v0, a0, (d1, d2), out0


def time_domain(mech, crank: CrankMotion, **kw) -> KEDResult:
    """Convenience wrapper: ``TimeDomain(mech, ...).run(crank, ...)``; keyword arguments are split
    between the constructor and :meth:`TimeDomain.run`."""
    run_keys = {"start", "steady_tol", "min_revolutions", "record_displacements", "callback", "chunk"}
    run_kw = {k: v for k, v in kw.items() if k in run_keys}
    init_kw = {k: v for k, v in kw.items() if k not in run_keys}
    return TimeDomain(mech, **init_kw).run(crank, **run_kw)
