"""The configurations of a time-domain model: for a batch of crank states, the instantaneous
structures factorized once and what a step reads of them (:class:`tmm_core.ConfigurationBatch`:
the factor, the load-to-response maps or stored factorizations, the rigid-body loads and the
estimated axial forces of each crank state).

Speed: for every distinct crank position the structure is factorized once and the dense maps
from nodal loads to nodal displacements, drive torque, gauge strains and segment axial forces are
stored (unit loads pushed through the Riccati factorization, batched: :mod:`tmm_core.step_data`).
A constant-speed run re-uses the maps of one revolution and marches them in the compiled kernel
(:mod:`tmm_core.compiled.march`); other crank histories are processed in chunks.

Owns: :func:`configurations` and the choice between maps, stored factorizations and sweeps.
Boundaries: the model is a :class:`tmm_core.discretization.Discretization`; the maps themselves
are :mod:`tmm_core.step_data`'s.
"""
from __future__ import annotations

import math

import numpy as np

from .compiled import statics as compiled_statics
from .configuration_batch import ConfigurationBatch, CrankStates
from .discretization import Discretization
from .errors import DynamicStabilityError, InputError
from .ked import Coupling, coupling_stiffness, linear_axial_forces, quasi_static, rigid_body_loads, segment_forces
from . import step_data
from .structure import LoadCase, factorize

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


def configurations(model: Discretization, angle, speed, accel, dt, maps: bool | str = "auto",
                   axial_force=None) -> ConfigurationBatch:
    """Factorize the instantaneous structures of ``model`` at a batch of crank states (angle
    [rad], speed [rad/s], acceleration [rad/s^2], step ``dt`` [s]) and return the affine maps
    from nodal loads (local, stacked) to nodal displacements, drive torque and gauge strains
    (and, for the 'dynamic' axial force, segment axial forces). ``maps``: True, "auto" (the maps
    only for models up to FACTORS_ABOVE_DOF with the compiled factorization, MAP_MAX_DOF
    without), "factors" (the compiled factorizations kept instead of maps:
    :class:`tmm_core.configuration_batch.StepFactors`) or False (the numpy factorization, built
    when a step asks for it). Beyond max_map_bytes neither maps nor factors are kept.
    ``axial_force``: stacked segment forces ``(B, n_seg)`` [N] for the field matrices instead of
    the quasi-static estimate."""
    mech = model.mech
    motion = mech.motion(angle, speed, accel)
    c_a, c_v = model.integrator.coefficients(dt)
    Kn = coupling_stiffness(mech, motion, model.coupling, c_a, c_v)
    factors, _ = model.link_factor(c_v, dt)
    loads_local = rigid_body_loads(mech, motion, model.gravity, frame="local")
    P = _axial_estimate(model, (angle, speed, accel), motion, loads_local, axial_force)
    keep_maps = with_maps(model, len(angle), maps)
    joints_flat = mech.joint_positions(motion)
    joints = {k: v[:, None, :] for k, v in joints_flat.items()}
    # Batch (B, 1): the second axis carries the unit loads. Gravity acts through the lumped
    # node masses (rigid_body_loads), like every other inertial load.
    case = LoadCase(joints, {}, {}, {k: v[:, None] for k, v in Kn.items()}, frame="local")

    def make_factor():
        return factorize(model.structure, case, None if P is None else {k: v[:, None] for k, v in P.items()},
                         check_buckling=False, stiffness_factor=factors, count_inertia=True)

    prep = None
    if maps is not False and model.compiled_factorization:
        # The maps come from the compiled factorization (tmm_core.compiled.structure); without
        # them ('factors', or too many DOFs or bytes) the compiled factorizations are kept
        # instead (tmm_core.compiled.time_step: linear in the segments), within the same memory
        # budget. The numpy factor is built only if a step asks for it (ConfigurationBatch.factor).
        prep = compiled_statics.prepare(model.structure, LoadCase(joints_flat, {}, {}, Kn, frame="local"),
                                        stiffness_factor=factors)
        if not keep_maps and compiled_statics.stored_bytes(prep) > model.max_map_bytes:
            prep = None
    step_factors, step_maps, factor = None, None, None
    drive = mech.drive_torque_terms(motion, model.gravity)
    if prep is not None:
        P_stacked = compiled_statics.stack_segments(prep, P or {})
        if keep_maps:
            step_maps, negative = step_data.compiled_maps(model, prep, P_stacked, drive)
        else:
            step_factors, negative = step_data.compiled_factors(model, prep, P_stacked, drive)
    else:
        factor = make_factor()
        negative = factor.negative_eigenvalues
    indefinite = np.any(np.reshape(negative, (len(angle), -1)) > 0, axis=-1)
    if np.any(indefinite) and (model.axial_force != "dynamic" or axial_force is not None):
        # The axial forces are those the step uses: the step's dynamic system is indefinite.
        raise DynamicStabilityError(
            f"the dynamic system of the time step (stiffness with the axial forces, plus the step's inertia) is "
            f"not positive definite at crank angle {math.degrees(float(angle[np.argmax(indefinite)])):.6g} deg: "
            "the links buckle even with their inertia; the transfer-matrix model cannot continue (a smaller step "
            "adds inertia)")
    if prep is None and keep_maps:
        step_maps = step_data.numpy_maps(model, factor, drive)
    P0 = None if P is None else np.concatenate([P[l.name] for l in model.links], axis=-1)
    crank = CrankStates(np.asarray(angle, float), np.asarray(speed, float), np.asarray(accel, float))
    # Configurations whose estimated axial forces leave the step indefinite: the dynamic step
    # refactorizes them at its own axial forces.
    return ConfigurationBatch(crank, motion, model.stack(loads_local), drive, P0, indefinite, step_maps,
                              make_factor, step_factors, {} if factor is None else {"factor": factor})


def _axial_estimate(model: Discretization, states, motion, loads_local, axial_force):
    """The axial forces ``{link: (B, n)}`` [N] of the field matrices at the crank ``states``
    ``(angle, speed, accel)``: ``axial_force`` (stacked, given), the linear (rigid-body)
    estimate of the 'dynamic' step on the compiled factorization, the quasi-static one, or None
    (linear theory)."""
    mech = model.mech
    if axial_force is not None:
        cuts = np.cumsum([l.total_segments for l in model.links])[:-1]
        return dict(zip([l.name for l in model.links], np.split(np.asarray(axial_force, dtype=float), cuts, axis=-1)))
    if model.axial_force == "dynamic" and model.compiled_factorization:
        # The dynamic step iterates from the linear (rigid-body) estimate, which exists beyond
        # the static Euler load too (the linear quasi_static below, its axial forces alone).
        return linear_axial_forces(mech, motion, model.gravity, loads_local)
    if model.axial_force != "none":
        # The axial forces only enter the field matrices (1e-8 relative is ample); the
        # quasi-static model uses the beam-column estimate, whose segment forces are the ones
        # in its field matrices.
        angle, speed, accel = states
        qs = quasi_static(mech, angle, speed, accel, beam_column=model.axial_force == "quasi_static",
                          coupling=Coupling(), gravity=model.gravity, tol=1e-8, backend=model.backend)
        return {k: segment_forces(r) for k, r in qs.solution.members.items()}
    return None


def with_maps(model: Discretization, B: int, maps) -> bool:
    """Whether a batch of ``B`` configurations gets the dense maps (``maps`` as
    :func:`configurations`): asked for or "auto" below the size limit, within max_map_bytes."""
    n_rows = model.n_dof + model.outputs.size + (len(model.segments.length) if model.axial_force == "dynamic" else 0)
    n_bytes = 8.0 * B * model.n_dof * n_rows
    if maps not in (True, False, "auto", "factors"):
        raise InputError(f"configurations: maps must be True, False, 'auto' or 'factors', got {maps!r}")
    largest = FACTORS_ABOVE_DOF if model.compiled_factorization else MAP_MAX_DOF
    return (maps is True or (maps == "auto" and model.n_dof <= largest)) and n_bytes <= model.max_map_bytes
