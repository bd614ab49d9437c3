"""The source documents' rigs as mechanisms (SI), for scripts and tests that vary one parameter.

Each builder loads the rig's scenario file (the single description of its geometry, materials
and masses) and changes only what its arguments ask for: mesh, damping, stiffness. Defaults
reproduce the analyses the scripts and tests were written for (no damping unless asked). Each
``*_scenario`` builder returns the whole scenario (for an engine that reads one); the builder of
the same name without the suffix returns its mechanism.
"""
from __future__ import annotations

import functools

from cosim import scenario as sc
from cosim.scenario import Scenario
from tmm_core import FourBarMechanism, StandardLinearSolid

LINKS = ("crank", "coupler", "rocker")


@functools.lru_cache(maxsize=None)
def _scenario(name: str):
    return sc.load(name)


def _build(name: str, overrides: dict) -> Scenario:
    return _scenario(name).with_overrides(overrides)


def _segments(n, links=LINKS):
    return {f"links.{link}.segments": n for link in links}


def _damping(ratio, frequency_Hz, links=LINKS):
    return {f"links.{link}.damping": {"ratio": f"{ratio * 100} %", "frequency": f"{frequency_Hz} Hz"} for link in links}


def _scale_modulus(scenario: str, material: str, factor):
    E = _scenario(scenario).raw["materials"][material]["E"]
    value = E["value"] if isinstance(E, dict) else E
    return {f"materials.{material}.E": f"({value}) * {factor!r}"}


def alexander_lawrence_scenario(n: int = 8, damping: float = 0.0, damping_Hz: float = 47.0, E_factor: float = 1.0,
                                bearing_lb: float = 0.06) -> Scenario:
    """Shin §8.3 (scenarios/alexander_lawrence_400rpm.toml) with ``n`` segments per link, modal
    ``damping`` at ``damping_Hz`` on every link (none by default), the modulus scaled by
    ``E_factor`` and ``bearing_lb`` at each coupler end."""
    name = "alexander_lawrence_400rpm"
    over = {**_segments(n), **_damping(damping, damping_Hz)}
    if E_factor != 1.0:
        over.update(_scale_modulus(name, "aluminium", E_factor))
    for i in range(len(_scenario(name).raw["links"]["coupler"]["point_masses"])):
        over[f"links.coupler.point_masses[{i}].mass"] = f"{bearing_lb} lb"
    return _build(name, over)


def alexander_lawrence(*args, **kwargs) -> FourBarMechanism:
    """The mechanism of :func:`alexander_lawrence_scenario` (same arguments)."""
    return alexander_lawrence_scenario(*args, **kwargs).mechanism


def fe_crank_rocker_scenario(n: int = 8, bearing_lbf: float = 0.13128, damping: float = 0.0, damping_Hz: float = 79.0,
                             crank_stiffness_factor: float | None = None) -> Scenario:
    """FE crank-rocker thesis rig (scenarios/base/fe_crank_rocker.toml) with ``n`` segments per
    link, ``bearing_lbf`` at each coupler end, modal ``damping`` on the coupler and rocker (none
    by default) and a rigid crank (the file's assumption), or an elastic crank with
    ``crank_stiffness_factor`` times the strip's modulus."""
    name = "crank_rocker_373rpm"
    over = {**_segments(n), **_damping(damping, damping_Hz, ("coupler", "rocker"))}
    for i in range(len(_scenario(name).raw["links"]["coupler"]["point_masses"])):
        over[f"links.coupler.point_masses[{i}].weight"] = f"{bearing_lbf} lbf"
    if crank_stiffness_factor is not None:
        over.update({"materials.crank_stiffened": {"E": f"{10.3e6 * crank_stiffness_factor} psi",
                                                   "density": "5.292 slug/ft^3"},
                     "links.crank.material": "crank_stiffened", "links.crank.rigid": False})
    return _build(name, over)


def fe_crank_rocker(*args, **kwargs) -> FourBarMechanism:
    """The mechanism of :func:`fe_crank_rocker_scenario` (same arguments)."""
    return fe_crank_rocker_scenario(*args, **kwargs).mechanism


def wang_steel_scenario(n: int = 4, depth_in: float = 0.062) -> Scenario:
    """Wang's steel four-bar (scenarios/wang_steel_342rpm.toml) with ``n`` segments per flexible
    span and strip depth ``depth_in`` (0.062 in his code, 0.055 in his text)."""
    return _build("wang_steel_342rpm", {**_segments(n, ("coupler", "rocker")), "sections.strip.depth": f"{depth_in} in"})


def wang_steel(*args, **kwargs) -> FourBarMechanism:
    """The mechanism of :func:`wang_steel_scenario` (same arguments)."""
    return wang_steel_scenario(*args, **kwargs).mechanism


def _composite_sls() -> StandardLinearSolid:
    return _scenario("wang_composite_297rpm").mechanism.coupler.viscoelastic


#: Assumed standard-linear-solid constants of Wang's +/-45 deg graphite-epoxy (declared in
#: scenarios/base/wang_composite.toml).
WANG_COMPOSITE_SLS = _composite_sls()


def wang_composite_scenario(n: int = 4, sls: StandardLinearSolid = WANG_COMPOSITE_SLS) -> Scenario:
    """Wang's +/-45 deg composite four-bar (scenarios/base/wang_composite.toml) with ``n``
    segments per flexible span and the given standard-linear-solid constants."""
    return _build("wang_composite_297rpm", {
        **_segments(n, ("coupler", "rocker")),
        "materials.composite.viscoelastic": {"instantaneous_modulus": f"{sls.instantaneous_modulus_Pa} Pa",
                                             "relaxed_modulus": f"{sls.relaxed_modulus_Pa} Pa",
                                             "relaxation_time": f"{sls.relaxation_time_s} s"},
        "materials.composite.E": f"{sls.instantaneous_modulus_Pa} Pa"})


def wang_composite(*args, **kwargs) -> FourBarMechanism:
    """The mechanism of :func:`wang_composite_scenario` (same arguments)."""
    return wang_composite_scenario(*args, **kwargs).mechanism
