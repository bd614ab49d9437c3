"""The source documents' rigs as mechanisms (SI), for scripts and tests that vary one parameter.

Each builder loads the rig's scenario file (the single description of its geometry, materials
and masses) and changes only what its arguments ask for: mesh, damping, stiffness. Defaults
reproduce the analyses the scripts and tests were written for (no damping unless asked).
"""
from __future__ import annotations

import copy
import functools

from cosim import scenario as sc
from tmm_core import FourBarMechanism, StandardLinearSolid

LINKS = ("crank", "coupler", "rocker")


@functools.lru_cache(maxsize=None)
def _raw(name: str) -> dict:
    """The merged TOML tree of a scenario (cached; callers get a copy)."""
    path = sc.SCENARIO_DIR / f"{name}.toml"
    return sc._read_with_bases(path, [])


def _build(name: str, edit) -> FourBarMechanism:
    raw = copy.deepcopy(_raw(name))
    edit(raw)
    return sc.from_dict(raw, f"{name} (rigs.py)").mechanism


def _segments(raw, n, links=LINKS):
    for link in links:
        raw["links"][link]["segments"] = n


def _damping(raw, ratio, frequency_Hz, links=LINKS):
    for link in links:
        if ratio:
            raw["links"][link]["damping"] = {"ratio": f"{ratio * 100} %", "frequency": f"{frequency_Hz} Hz"}
        else:
            raw["links"][link].pop("damping", None)


def _scale_modulus(raw, material, factor):
    E = raw["materials"][material]["E"]
    value = E["value"] if isinstance(E, dict) else E
    raw["materials"][material]["E"] = f"({value}) * {factor!r}"


def alexander_lawrence(n: int = 8, damping: float = 0.0, damping_Hz: float = 47.0, E_factor: float = 1.0,
                       bearing_lb: float = 0.06) -> FourBarMechanism:
    """Shin §8.3 (scenarios/alexander_lawrence_400rpm.toml) with ``n`` segments per link, modal
    ``damping`` at ``damping_Hz`` on every link (none by default), the modulus scaled by
    ``E_factor`` and ``bearing_lb`` at each coupler end."""
    def edit(raw):
        _segments(raw, n)
        _damping(raw, damping, damping_Hz)
        if E_factor != 1.0:
            _scale_modulus(raw, "aluminium", E_factor)
        for pm in raw["links"]["coupler"]["point_masses"]:
            pm["mass"] = f"{bearing_lb} lb"
    return _build("alexander_lawrence_400rpm", edit)


def fe_crank_rocker(n: int = 8, bearing_lbf: float = 0.13128, damping: float = 0.0, damping_Hz: float = 79.0,
                    crank_stiffness_factor: float | None = None) -> FourBarMechanism:
    """FE crank-rocker thesis rig (scenarios/base/fe_crank_rocker.toml) with ``n`` segments per
    link, ``bearing_lbf`` at each coupler end, modal ``damping`` on the coupler and rocker (none
    by default) and a rigid crank (the file's assumption), or an elastic crank with
    ``crank_stiffness_factor`` times the strip's modulus."""
    def edit(raw):
        _segments(raw, n)
        _damping(raw, damping, damping_Hz, ("coupler", "rocker"))
        for pm in raw["links"]["coupler"]["point_masses"]:
            pm["weight"] = f"{bearing_lbf} lbf"
        if crank_stiffness_factor is not None:
            raw["materials"]["crank_stiffened"] = {"E": f"{10.3e6 * crank_stiffness_factor} psi",
                                                   "density": "5.292 slug/ft^3"}
            raw["links"]["crank"]["material"] = "crank_stiffened"
            raw["links"]["crank"]["rigid"] = False
    return _build("crank_rocker_373rpm", edit)


def wang_steel(n: int = 4, depth_in: float = 0.062) -> FourBarMechanism:
    """Wang's steel four-bar (scenarios/wang_steel_342rpm.toml) with ``n`` segments per flexible
    span and strip depth ``depth_in`` (0.062 in his code, 0.055 in his text)."""
    def edit(raw):
        _segments(raw, n, ("coupler", "rocker"))
        raw["sections"]["strip"]["depth"] = f"{depth_in} in"
    return _build("wang_steel_342rpm", edit)


def _composite_sls() -> StandardLinearSolid:
    return _build("wang_composite_297rpm", lambda raw: None).coupler.viscoelastic


#: Assumed standard-linear-solid constants of Wang's +/-45 deg graphite-epoxy (declared in
#: scenarios/base/wang_composite.toml).
WANG_COMPOSITE_SLS = _composite_sls()


def wang_composite(n: int = 4, sls: StandardLinearSolid = WANG_COMPOSITE_SLS) -> FourBarMechanism:
    """Wang's +/-45 deg composite four-bar (scenarios/base/wang_composite.toml) with ``n``
    segments per flexible span and the given standard-linear-solid constants."""
    def edit(raw):
        _segments(raw, n, ("coupler", "rocker"))
        ve = raw["materials"]["composite"]
        ve["viscoelastic"] = {"instantaneous_modulus": f"{sls.instantaneous_modulus_Pa} Pa",
                              "relaxed_modulus": f"{sls.relaxed_modulus_Pa} Pa",
                              "relaxation_time": f"{sls.relaxation_time_s} s"}
        ve["E"] = f"{sls.instantaneous_modulus_Pa} Pa"
    return _build("wang_composite_297rpm", edit)
