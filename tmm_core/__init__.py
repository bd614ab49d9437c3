"""Transfer-matrix method (TMM) solver for flexible planar linkages, after Shin (1986).

Pure numpy/scipy, no I/O. Units are SI throughout; see :mod:`tmm_core.matrices` for the state
vector and sign convention.

Owns: the public API of the solver. Boundaries: no cosim import, no I/O.
"""
from .errors import (AssemblyError, BucklingError, ConvergenceError, InputError, SingularStructureError,
                     TMMError)
from .kinematics import (FourBarGeometry, FourBarMotion, LinkMotion, SliderCrankGeometry, SliderCrankMotion,
                         fourbar_motion, slider_crank_motion)
from .matrices import field_matrix, frame_rotation, point_matrix, rigid_element_matrix, spring_matrix
from . import kernels
from .configuration_batch import ConfigurationBatch, CrankStates, OutputLayout, StepMaps
from .ked import Coupling, CrankMotion, KEDResult, quasi_static, rigid_body_loads
from .transient import TimeDomain
from .march import March, time_domain
from .materials import Damping, StandardLinearSolid
from .mechanism import FourBarMechanism, Link, PointMass, SliderCrankMechanism
from .post import (Gauge, bending_axial_strain, distortion, gauge_strains, soderberg, state_at, static_safety_factor,
                   surface_strains, surface_stresses)
from .reduced import ReducedBasis, ReducedOptions, build_basis
from .reduced_periodic import periodic_steady_state_reduced
from .riccati import chain_product, chain_states, condense_chain, factor_chain, sweep_loads
from .sections import Material, Section
from .statics import StaticSolution, external_resultant, solve_static
from .structure import Joint, LoadCase, Member, Structure, factorize, solve_factored, solve_linear

__all__ = [name for name in dir() if not name.startswith("_")]
