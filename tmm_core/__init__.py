"""Transfer-matrix method (TMM) solver for flexible planar linkages, after Shin (1986).

Pure numpy/scipy, no I/O. Units are SI throughout; see :mod:`tmm_core.matrices` for the state
vector and sign convention.

The names below are the user-level API, written out by hand: mechanisms and their parts, the
instantaneous structure and its statics, the rigid-body kinematics, the quasi-static and
time-domain analyses, the periodic steady state, natural frequencies, the reduced model, strains
and safety factors, and the errors. Step internals (configuration batches, step maps, the
compiled kernels) stay in their modules, importable from there.

Owns: the public API of the solver. Boundaries: no cosim import, no I/O.
"""
from .errors import (AssemblyError, BucklingError, ConvergenceError, InputError, SingularStructureError,
                     TMMError)
from .frequencies import fourbar_frequencies, frequency_model, natural_frequencies
from .ked import Coupling, CrankMotion, KEDResult, quasi_static, rigid_body_loads
from .kinematics import (FourBarGeometry, FourBarMotion, LinkMotion, SliderCrankGeometry, SliderCrankMotion,
                         fourbar_motion, slider_crank_motion)
from .linkage import LinkageMechanism, as_linkage
from .materials import Damping, StandardLinearSolid
from .mechanism import FourBarMechanism, Link, PointMass, SliderCrankMechanism
from .periodic import PeriodicResult, floquet_multipliers, periodic_steady_state
from .post import (Gauge, bending_axial_strain, distortion, gauge_strains, soderberg, state_at, static_safety_factor,
                   surface_strains, surface_stresses)
from .reduced import ReducedBasis, ReducedOptions, build_basis
from .reduced_periodic import periodic_steady_state_reduced
from .sections import Material, Section
from .statics import StaticSolution, external_resultant, solve_static
from .structure import Joint, LoadCase, Member, Structure
from .transient import TimeDomain, time_domain

__all__ = [
    # errors
    "TMMError", "InputError", "ConvergenceError", "BucklingError", "AssemblyError", "SingularStructureError",
    # materials, sections, links and mechanisms
    "Material", "Section", "Damping", "StandardLinearSolid", "Link", "PointMass",
    "FourBarMechanism", "SliderCrankMechanism", "LinkageMechanism", "as_linkage",
    # rigid-body kinematics
    "FourBarGeometry", "FourBarMotion", "SliderCrankGeometry", "SliderCrankMotion", "LinkMotion",
    "fourbar_motion", "slider_crank_motion",
    # the instantaneous structure and its statics
    "Structure", "Member", "Joint", "LoadCase", "solve_static", "StaticSolution", "external_resultant",
    # kineto-elastodynamics: quasi-static and time domain
    "Coupling", "CrankMotion", "KEDResult", "rigid_body_loads", "quasi_static", "TimeDomain", "time_domain",
    # periodic steady state
    "periodic_steady_state", "PeriodicResult", "floquet_multipliers",
    # natural frequencies
    "fourbar_frequencies", "frequency_model", "natural_frequencies",
    # the reduced model
    "ReducedBasis", "ReducedOptions", "build_basis", "periodic_steady_state_reduced",
    # strains, stresses and safety factors
    "Gauge", "gauge_strains", "bending_axial_strain", "surface_strains", "surface_stresses", "state_at",
    "distortion", "soderberg", "static_safety_factor",
]
