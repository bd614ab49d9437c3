"""Transfer-matrix method (TMM) solver for flexible planar linkages, after Shin (1986).

Pure numpy/scipy, no I/O. Units are SI throughout; see :mod:`tmm_core.matrices` for the state
vector and sign convention.

The names below are the user-level API, written out by hand: mechanisms and their parts, the
instantaneous structure and its statics, the rigid-body kinematics, the quasi-static and
time-domain analyses, the periodic steady state, natural frequencies, the reduced model, strains
and safety factors, and the errors. Step internals (configuration batches, step maps, the
compiled kernels) stay in their modules, importable from there.

Each name is loaded from its module when it is first used (PEP 562): a command that runs the
time domain does not pay for scipy's integrators and interpolators, which only the periodic
solver, the reduced model and the frequency functions need.

Owns: the public API of the solver. Boundaries: no cosim import, no I/O.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

#: Where each public name lives: {module (relative to the package): names}.
PUBLIC = {
    "errors": ("TMMError", "InputError", "ConvergenceError", "BucklingError", "AssemblyError",
               "SingularStructureError"),
    # materials, sections, links and mechanisms
    "sections": ("Material", "Section"),
    "materials": ("Damping", "StandardLinearSolid"),
    "mechanism": ("Link", "PointMass", "FourBarMechanism", "SliderCrankMechanism"),
    "linkage": ("LinkageMechanism", "as_linkage"),
    # rigid-body kinematics
    "kinematics": ("FourBarGeometry", "FourBarMotion", "SliderCrankGeometry", "SliderCrankMotion", "LinkMotion",
                   "fourbar_motion", "slider_crank_motion"),
    # the instantaneous structure and its statics
    "structure": ("Structure", "Member", "Joint", "LoadCase"),
    "statics": ("solve_static", "StaticSolution", "external_resultant"),
    # kineto-elastodynamics: quasi-static and time domain
    "ked": ("Coupling", "CrankMotion", "KEDResult", "rigid_body_loads", "quasi_static"),
    "transient": ("TimeDomain", "time_domain"),
    # periodic steady state
    "periodic": ("periodic_steady_state", "PeriodicResult", "ShootingOptions", "floquet_multipliers"),
    # natural frequencies
    "frequencies": ("fourbar_frequencies", "frequency_model", "natural_frequencies"),
    # the reduced model
    "reduced": ("ReducedBasis", "ReducedOptions", "build_basis"),
    "reduced_periodic": ("periodic_steady_state_reduced",),
    # strains, stresses and safety factors
    "post": ("Gauge", "gauge_strains", "bending_axial_strain", "surface_strains", "surface_stresses", "state_at",
             "distortion", "soderberg", "static_safety_factor"),
}
MODULE_OF = {name: module for module, names in PUBLIC.items() for name in names}

#: The public names, in the order of :data:`PUBLIC` (written out there, once).
__all__ = [name for names in PUBLIC.values() for name in names]


def __getattr__(name: str):
    """A public name, read from its module (imported on first use; later reads find the module in
    ``sys.modules``), or a submodule (``tmm_core.periodic``) as an eager package would have it."""
    module = MODULE_OF.get(name)
    if module is not None:
        return getattr(importlib.import_module(f".{module}", __name__), name)
    try:
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":      # the submodule exists and failed to import
            raise
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:      # for type checkers and IDEs, which do not run __getattr__
    from .errors import (AssemblyError, BucklingError, ConvergenceError, InputError, SingularStructureError,
                         TMMError)
    from .frequencies import fourbar_frequencies, frequency_model, natural_frequencies
    from .ked import Coupling, CrankMotion, KEDResult, quasi_static, rigid_body_loads
    from .kinematics import (FourBarGeometry, FourBarMotion, LinkMotion, SliderCrankGeometry, SliderCrankMotion,
                             fourbar_motion, slider_crank_motion)
    from .linkage import LinkageMechanism, as_linkage
    from .materials import Damping, StandardLinearSolid
    from .mechanism import FourBarMechanism, Link, PointMass, SliderCrankMechanism
    from .periodic import PeriodicResult, ShootingOptions, floquet_multipliers, periodic_steady_state
    from .post import (Gauge, bending_axial_strain, distortion, gauge_strains, soderberg, state_at,
                       static_safety_factor, surface_strains, surface_stresses)
    from .reduced import ReducedBasis, ReducedOptions, build_basis
    from .reduced_periodic import periodic_steady_state_reduced
    from .sections import Material, Section
    from .statics import StaticSolution, external_resultant, solve_static
    from .structure import Joint, LoadCase, Member, Structure
    from .transient import TimeDomain, time_domain
