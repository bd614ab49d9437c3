"""Issue 17: the bench's own bad-input corpus. Every case is data: a scenario variant (key paths
set or removed through ``Scenario.with_overrides``), a file, a record or a command line, and the
exact key (or flag, file, column) the refusal must name. One parametrized test per family; none of
these cases repeats one of tests/test_reliability.py or tests/test_bad_input.py.

A scenario case passes when the loader raises a :class:`ScenarioError` whose message names
``key '<key>'``; a record case when :func:`cosim.records.load_record` raises a RecordError naming
the key or column; a command-line case when ``cosim`` exits with status 2 and exactly one
``error:`` line on stderr naming the flag. Anything else (a traceback, a clean error naming
another key, an accepted value) is a bug of the loader."""
import tomllib
from pathlib import Path

import pytest
import tomli_w

from cosim.cli import main
from cosim.records import RECORD_DIR, RecordError, load_record
from cosim.scenario import ScenarioError, check_unknowns, load

CR, SC, WS, ST, WC = ("crank_rocker_373rpm", "slider_crank_600rpm", "watt_sixbar_600rpm", "shin_multiloop_small",
                      "wang_composite_280rpm")
_BASES = {}


def _base(name):
    if name not in _BASES:
        _BASES[name] = load(name)
    return _BASES[name]


def refuses(name, overrides, key):
    with pytest.raises(ScenarioError) as err:
        _base(name).with_overrides(overrides)
    assert f"key '{key}'" in str(err.value), str(err.value)


def case(*args, id=None):
    return pytest.param(*args, id=id)


# -- keys: unknown, misspelt, missing, a table where a value belongs and back ------------------------
KEYS = [
    (CR, {"scenario.nmae": "x"}, "scenario.nmae"),
    (CR, {"linkage.grund": "11 in"}, "linkage.grund"),
    (CR, {"links.coupler.lenght": "10 in"}, "links.coupler.lenght"),
    (CR, {"drive.sped": "100 rpm"}, "drive.sped"),
    (CR, {"solver.tmm.segmnts": 4}, "solver.tmm.segmnts"),
    (CR, {"solver.exudyn.elemnts": 4}, "solver.exudyn.elemnts"),
    (CR, {"solver.mujoco.stp": "1 deg"}, "solver.mujoco.stp"),
    (CR, {"solver.abaqus": {}}, "solver.abaqus"),
    (CR, {"output.revs": 2}, "output.revs"),
    (CR, {"coupling.schem": "jacobi"}, "coupling.schem"),
    (CR, {"links.coupler.point_masses[0].mas": "1 kg"}, "links.coupler.point_masses[0].mas"),
    (CR, {"linkage": None}, "linkage"),
    (CR, {"links": None}, "links"),
    (CR, {"links.rocker": None}, "links.rocker"),
    (CR, {"links.coupler.length": None}, "links.coupler.length"),
    (CR, {"links.coupler.section": None}, "links.coupler.section"),
    (CR, {"linkage.type": None}, "linkage.type"),
    (CR, {"links.extra": {"length": "1 in", "section": "strip", "material": "aluminium"}}, "links.extra"),
    (CR, {"linkage": "four-bar"}, "linkage"),
    (CR, {"linkage.type": 4}, "linkage.type"),
    (CR, {"linkage.type": "five-bar"}, "linkage.type"),
    (CR, {"links": []}, "links"),
    (CR, {"links.coupler": "10 in"}, "links.coupler"),
    (CR, {"drive": "373 rpm"}, "drive"),
    (CR, {"solver.tmm": "fast"}, "solver.tmm"),
    (CR, {"solver": 5}, "solver"),
    (CR, {"gravity": "down"}, "gravity"),
    (CR, {"gravity": {"vector": ["0 m/s^2", "-9.81 m/s^2"], "g": 1}}, "gravity.g"),
    (SC, {"joints": {}}, "joints"),
    (SC, {"links.rocker": {"length": "1 in", "section": "strip", "material": "steel"}}, "links.rocker"),
    (ST, {"drive": {"speed": "1 rpm"}}, "drive"),                     # was ignored by a structure
    (ST, {"gauges": {"g": {"link": "x", "position": "1 in"}}}, "gauges"),
    (ST, {"motor": {"rated_power": "1 hp"}}, "motor"),
    (ST, {"joints": 5}, "joints"),
    (CR, {"uncertainty.samples": 0}, "uncertainty.samples"),
    (CR, {"uncertainty.samples": 10 ** 8}, "uncertainty.samples"),   # its design alone would not fit
    (CR, {"uncertainty.seed": "1"}, "uncertainty.seed"),
    (CR, {"uncertainty.identify": "damping"}, "uncertainty.identify"),
    (CR, {"uncertainty.identify": ["nope"]}, "uncertainty.identify"),                             # was accepted
    (CR, {"uncertainty.parameters.damping.keys": ["links.nope.damping.ratio"]},
     "uncertainty.parameters.damping.keys"),                                                     # was accepted
    (CR, {"uncertainty.parameters": 5}, "uncertainty.parameters"),
    (CR, {"uncertainty.parameters.damping.distribution": "cauchy"}, "uncertainty.parameters.damping.distribution"),
    # Issue 32: each unknown at the edges of its range must be a scenario the loader accepts.
]


@pytest.mark.parametrize("name, overrides, key", KEYS)
def test_keys(name, overrides, key):
    refuses(name, overrides, key)


# -- the [uncertainty] table's values, checked where they are read (cosim uncertainty, identify) --------
UNKNOWNS = [
    (CR, {"uncertainty.parameters.damping.unit": ""}, "uncertainty.parameters.damping.low"),      # every sample failed
    (CR, {"uncertainty.parameters.damping.high": "150 %"}, "uncertainty.parameters.damping.high"),  # was accepted
    (CR, {"uncertainty.parameters.coupler_face.values": ["top", "side"]}, "uncertainty.parameters.coupler_face.values"),
    (CR, {"uncertainty.parameters.modulus.low": "-1 psi"}, "uncertainty.parameters.modulus.low"),
]


@pytest.mark.parametrize("name, overrides, key", UNKNOWNS)
def test_unknowns(name, overrides, key):
    """Each unknown at the edges of its range must make a scenario the loader accepts; checked
    before the first sample or fit (every one of them failed alike)."""
    with pytest.raises(ScenarioError) as err:
        check_unknowns(_base(name).with_overrides(overrides))
    assert f"key '{key}'" in str(err.value), str(err.value)


# -- units: no unit, the wrong dimension, text pint cannot or must not read ------------------------
UNITS = [
    (CR, {"linkage.ground": "11"}, "linkage.ground"),
    (CR, {"linkage.ground": 11}, "linkage.ground"),
    (CR, {"linkage.ground": "11 kg"}, "linkage.ground"),
    (CR, {"linkage.ground": "11 furlongs per"}, "linkage.ground"),
    (CR, {"linkage.ground": "11 inn"}, "linkage.ground"),
    (CR, {"drive.speed": "373 Hz*m"}, "drive.speed"),
    (CR, {"drive.speed": "373 rpm rpm"}, "drive.speed"),
    (CR, {"drive.speed": "1e400 rpm"}, "drive.speed"),
    (CR, {"drive.speed": "373 rpm + 1 in"}, "drive.speed"),
    (CR, {"drive.speed": "373 degC"}, "drive.speed"),
    (CR, {"drive.speed": "2**1000 rpm"}, "drive.speed"),
    (CR, {"drive.speed": "373 rpm**2"}, "drive.speed"),
    (CR, {"drive.speed": "__import__('os') rpm"}, "drive.speed"),
    (CR, {"drive.speed": "373 * rpm / 0"}, "drive.speed"),
    (CR, {"drive.speed": "3,73 rpm"}, "drive.speed"),               # was read as 373 rpm
    (CR, {"drive.speed": "[373] rpm"}, "drive.speed"),
    (CR, {"drive.speed": [373, "rpm"]}, "drive.speed"),
    (CR, {"drive.speed": 373}, "drive.speed"),
    (CR, {"drive.start_angle": "90"}, "drive.start_angle"),          # was 90 rad
    (CR, {"drive.start_angle": "90 rpm"}, "drive.start_angle"),
    (CR, {"drive.start_angle": "1e30 deg"}, "drive.start_angle"),
    (CR, {"linkage.ground_angle": 30}, "linkage.ground_angle"),       # was 30 rad
    (CR, {"linkage.ground_angle": "1 in"}, "linkage.ground_angle"),
    (CR, {"solver.tmm.step": 0.001}, "solver.tmm.step"),              # was 0.001 rad
    (CR, {"solver.tmm.step": "1 m"}, "solver.tmm.step"),
    (CR, {"solver.mujoco.step": "1 kg"}, "solver.mujoco.step"),
    (CR, {"solver.exudyn.step": "abc"}, "solver.exudyn.step"),
    (CR, {"output.steady_tolerance": "0.5 in"}, "output.steady_tolerance"),
    (CR, {"gravity": {"vector": ["0 m/s^2", "9.81"]}}, "gravity.vector[1]"),
    (CR, {"gravity": {"vector": ["0 m/s^2"]}}, "gravity.vector"),
    (SC, {"linkage.offset": "1 kg"}, "linkage.offset"),
    (SC, {"linkage.slide_angle": "1 in"}, "linkage.slide_angle"),
    (SC, {"linkage.slide_angle": 45}, "linkage.slide_angle"),         # was 45 rad
    # Angles are dimensionless to pint: each of these was read silently as something else.
    (CR, {"drive.speed": "10 1/s"}, "drive.speed"),                   # was 10 rad/s
    (CR, {"drive.speed": "95 rpm/rad"}, "drive.speed"),               # was 95 rpm
    (CR, {"links.coupler.length": "7 in/rad"}, "links.coupler.length"),  # was 7 in
    (CR, {"drive.start_angle": "1 deg deg"}, "drive.start_angle"),    # was 0.0175 deg
    (CR, {"solver.tmm.step": "1 deg deg"}, "solver.tmm.step"),
    (CR, {"materials.aluminium.E": "10e6 psi*rad"}, "materials.aluminium.E"),
    # Issue 32: angles whose fraction of a turn is lost in floating point (1e19 deg: doubles 32 rad apart).
    (CR, {"linkage.ground_angle": "1e19 deg"}, "linkage.ground_angle"),     # was accepted
    (CR, {"drive.start_angle": "-1e6 deg"}, "drive.start_angle"),          # was accepted
    (SC, {"linkage.slide_angle": "1e19 deg"}, "linkage.slide_angle"),       # was accepted
    (WS, {"linkage.crank_zero": "1e19 deg"}, "linkage.crank_zero"),         # was accepted
    (ST, {"joints.13.direction": "1e19 deg"}, "joints.13.direction"),       # was accepted
]


@pytest.mark.parametrize("name, overrides, key", UNITS)
def test_units(name, overrides, key):
    refuses(name, overrides, key)


# -- geometry: lengths, sections, the linkage's assembly, point masses and end blocks ---------------
GEOMETRY = [
    (CR, {"linkage.ground": "0 in"}, "linkage.ground"),
    (CR, {"linkage.ground": "-11 in"}, "linkage.ground"),
    (CR, {"linkage.ground": "40 in"}, "linkage"),
    (CR, {"links.crank.length": "0 in"}, "links.crank.length"),
    (CR, {"links.coupler.length": "-10 in"}, "links.coupler.length"),
    (CR, {"links.crank.length": "12 in"}, "linkage"),
    (CR, {"links.rocker.length": "8 in"}, "linkage"),          # 7/10/8/11, s + l = p + q: was a NaN in the TMM
    (CR, {"links.crank.length": "6 in", "links.rocker.length": "7 in"}, "linkage"),     # 6/10/7/11: likewise
    (CR, {"linkage.branch": "closed"}, "linkage.branch"),
    (CR, {"linkage.pivot": ["0 in"]}, "linkage.pivot"),
    (CR, {"linkage.pivot": "0 in"}, "linkage.pivot"),
    (CR, {"linkage.pivot": ["0 in", "x"]}, "linkage.pivot[1]"),
    (CR, {"sections.strip.width": "0 in"}, "sections.strip.width"),
    (CR, {"sections.strip.depth": "-0.125 in"}, "sections.strip.depth"),
    (CR, {"sections.strip.area": "1 in^2"}, "sections.strip"),
    (CR, {"sections.strip.width": None}, "sections.strip.width"),
    (CR, {"sections.strip.width": None, "sections.strip.area": "0.125 in^2", "sections.strip.inertia": "1 in"},
     "sections.strip.inertia"),
    (CR, {"sections.strip.height": "1 in"}, "sections.strip.height"),
    (CR, {"sections.strip.depth": None}, "sections.strip.depth"),
    (CR, {"links.coupler.section": "rod"}, "links.coupler.section"),
    (CR, {"links.coupler.section": 5}, "links.coupler.section"),
    (CR, {"links.coupler.segments": 0}, "links.coupler.segments"),
    (CR, {"links.coupler.segments": 2.5}, "links.coupler.segments"),
    (CR, {"links.coupler.segments": "4"}, "links.coupler.segments"),
    (CR, {"links.coupler.rigid": True}, "links.coupler.rigid"),
    (CR, {"links.crank.rigid": "yes"}, "links.crank.rigid"),
    (CR, {"links.coupler.point_masses": {"position": "0 in"}}, "links.coupler.point_masses"),
    (CR, {"links.coupler.point_masses": [5]}, "links.coupler.point_masses[0]"),
    (CR, {"links.coupler.point_masses[0].weight": "-1 lbf"}, "links.coupler.point_masses[0].weight"),
    (CR, {"links.coupler.point_masses[0].weight": "1 lb"}, "links.coupler.point_masses[0].weight"),
    (CR, {"links.coupler.point_masses[0].mass": "1 kg"}, "links.coupler.point_masses[0]"),
    (CR, {"links.coupler.point_masses[0].weight": None}, "links.coupler.point_masses[0]"),
    (CR, {"links.coupler.point_masses[0].position": None}, "links.coupler.point_masses[0].position"),
    (CR, {"links.coupler.point_masses[0].inertia": "-1 kg*m^2"}, "links.coupler.point_masses[0].inertia"),
    (CR, {"links.coupler.point_masses[0].inertia": "1 kg"}, "links.coupler.point_masses[0].inertia"),
    (CR, {"links.coupler.start_block": {"length": "1 in", "section": "strip"}}, "links.coupler.start_block.material"),
    (CR, {"links.coupler.start_block": {"length": "20 in", "section": "strip", "material": "aluminium"}},
     "links.coupler"),
    (CR, {"links.coupler.end_block": {"length": "1 in", "section": "nope", "material": "aluminium"}},
     "links.coupler.end_block.section"),
    (CR, {"links.coupler.start_block": "1 in"}, "links.coupler.start_block"),
    (SC, {"linkage.slider_mass": "1 kg"}, "linkage.slider_mass"),
    (SC, {"linkage.slider_weight": "-1 lbf"}, "linkage.slider_weight"),
    (SC, {"linkage.offset": "20 in"}, "linkage"),
    (SC, {"linkage.ground": "11 in"}, "linkage.ground"),
    (WS, {"joints.B.position": ["3 in"]}, "joints.B.position"),
    (WS, {"joints.B.position": "3 in"}, "joints.B.position"),
    (WS, {"joints.A.support": "welded"}, "joints.A.support"),
    (WS, {"links.coupler.path": ["B", "Z"]}, "links.coupler.path"),
    (WS, {"links.coupler.path": ["B"]}, "links.coupler.path"),
    (WS, {"links.coupler.path": "B"}, "links.coupler.path"),
    (WS, {"modules[1].type": "xyz"}, "modules[1].type"),
    (WS, {"modules[1].joint": "Z"}, "modules[1].joint"),
    (WS, {"modules[1].links": ["coupler"]}, "modules[1].links"),
    (WS, {"modules[0].link": "nope"}, "modules[0].link"),              # was named 'modules[0]'
    (WS, {"modules": 5}, "modules"),
    (WS, {"modules": []}, "modules"),
    (WS, {"linkage.crank": "nope"}, "linkage.crank"),
    (WS, {"joints": 5}, "joints"),
    (WS, {"links.coupler.length": "1 in"}, "links.coupler.length"),
    (WS, {"loads": {"l": {"joint": "Q", "force": ["1 N", "0 N"]}}}, "loads.l.joint"),
    (WS, {"plates": 5}, "plates"),
    (WS, {"springs": {"s": {"joints": ["A"]}}}, "springs.s.joints"),
]


@pytest.mark.parametrize("name, overrides, key", GEOMETRY)
def test_geometry(name, overrides, key):
    refuses(name, overrides, key)


# -- materials ----------------------------------------------------------------------------------------
MATERIALS = [
    (CR, {"materials.aluminium.youngs": "1 psi"}, "materials.aluminium.youngs"),
    (CR, {"materials.aluminium.E": None}, "materials.aluminium.E"),
    (CR, {"materials.aluminium.density": None}, "materials.aluminium.density"),
    (CR, {"materials.aluminium.E": "10.3e6 psi/in"}, "materials.aluminium.E"),
    (CR, {"materials.aluminium.E": "10.3e6"}, "materials.aluminium.E"),
    (CR, {"materials.aluminium.E": "10.3e6 lb"}, "materials.aluminium.E"),
    (CR, {"materials.aluminium.E": "-10.3e6 psi"}, "materials.aluminium.E"),
    (CR, {"materials.aluminium.E": "10.3 psi"}, "materials.aluminium.E"),          # far too soft
    (CR, {"materials.aluminium.density": "5.292 slug"}, "materials.aluminium.density"),
    (CR, {"materials.aluminium.density": "-5 kg/m^3"}, "materials.aluminium.density"),
    (CR, {"materials.aluminium.density": "1e25 kg/m^3"}, "materials.aluminium.density"),
    (CR, {"materials.aluminium.yield_strength": "0 MPa"}, "materials.aluminium.yield_strength"),
    (CR, {"materials.aluminium.yield_strength": "200"}, "materials.aluminium.yield_strength"),
    (CR, {"materials.aluminium.poisson": "0.3"}, "materials.aluminium.poisson"),
    (CR, {"materials.aluminium.poisson": 0.7}, "materials.aluminium.poisson"),      # was named 'materials.aluminium'
    (CR, {"materials.aluminium.poisson": -2}, "materials.aluminium.poisson"),
    (CR, {"materials.aluminium.endurance_limit": "-1 MPa"}, "materials.aluminium.endurance_limit"),
    (CR, {"materials.aluminium.viscoelastic": 5}, "materials.aluminium.viscoelastic"),
    (CR, {"materials.aluminium.viscoelastic": {"instantaneous_modulus": "10.3e6 psi"}},
     "materials.aluminium.viscoelastic.relaxation_time"),
    (CR, {"materials.aluminium.viscoelastic": {"instantaneous_modulus": "10.3e6 psi", "relaxed_modulus": "20e6 psi",
                                                "relaxation_time": "1 ms"}}, "materials.aluminium.viscoelastic"),
    (CR, {"materials.aluminium.viscoelastic": {"instantaneous_modulus": "9e6 psi", "relaxed_modulus": "5e6 psi",
                                                "relaxation_time": "1 ms"}}, "materials.aluminium.E"),
    (CR, {"materials.aluminium": {"E": "10.3e6 psi", "density": "5.292 slug/ft^3", "E2": 1}}, "materials.aluminium.E2"),
    (CR, {"materials": {}}, "links.crank.material"),
    (CR, {"links.coupler.material": "steel"}, "links.coupler.material"),
    (CR, {"links.coupler.material": ["aluminium"]}, "links.coupler.material"),
    (WC, {"materials": None}, "links.crank.material"),
]


@pytest.mark.parametrize("name, overrides, key", MATERIALS)
def test_materials(name, overrides, key):
    refuses(name, overrides, key)


# -- damping ------------------------------------------------------------------------------------------
DAMPING = [
    (CR, {"links.coupler.damping.zeta": "2 %"}, "links.coupler.damping.zeta"),
    (CR, {"links.coupler.damping.ratio": "-2 %"}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.ratio": "100 %"}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.ratio": "2 % Hz"}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.ratio": "% 2"}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.ratio": "nan %"}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.ratio": True}, "links.coupler.damping.ratio"),
    (CR, {"links.coupler.damping.frequency": None}, "links.coupler.damping.frequency"),
    (CR, {"links.coupler.damping.frequency": "0 Hz"}, "links.coupler.damping.frequency"),
    (CR, {"links.coupler.damping.frequency": "79"}, "links.coupler.damping.frequency"),
    (CR, {"links.coupler.damping.frequency": "79 m"}, "links.coupler.damping.frequency"),
    (CR, {"links.coupler.damping.stiffness": "1e-5 s"}, "links.coupler.damping"),
    (CR, {"links.coupler.damping": {"stiffness": "-1e-5 s"}}, "links.coupler.damping.stiffness"),
    (CR, {"links.coupler.damping": {"mass": "1 s"}}, "links.coupler.damping.mass"),
    (CR, {"links.coupler.damping": {"stiffness": "1e-5"}}, "links.coupler.damping.stiffness"),
    (CR, {"links.coupler.damping": "2 %"}, "links.coupler.damping"),
    (CR, {"links.coupler.damping": {"stiffness": "1e6 s"}}, "links.coupler.damping.stiffness"),     # was accepted
    (CR, {"links.coupler.damping": {"mass": "1e12 1/s"}}, "links.coupler.damping.mass"),           # was accepted
    (CR, {"links.crank.damping": {"ratio": "2 %", "frequency": "79 Hz"}}, "links.crank.damping"),
]


@pytest.mark.parametrize("name, overrides, key", DAMPING)
def test_damping(name, overrides, key):
    refuses(name, overrides, key)


# -- gauges -------------------------------------------------------------------------------------------
GAUGES = [
    (CR, {"gauges.coupler_mid.side": "top"}, "gauges.coupler_mid.side"),
    (CR, {"gauges.coupler_mid.link": None}, "gauges.coupler_mid.link"),
    (CR, {"gauges.coupler_mid.position": None}, "gauges.coupler_mid.position"),
    (CR, {"gauges.coupler_mid.link": "crank"}, "gauges.coupler_mid.link"),
    (CR, {"gauges.coupler_mid.link": "ground"}, "gauges.coupler_mid.link"),
    (CR, {"gauges.coupler_mid.link": 3}, "gauges.coupler_mid.link"),
    (CR, {"gauges.coupler_mid.position": "11 in"}, "gauges.coupler_mid.position"),
    (CR, {"gauges.coupler_mid.position": "-1 in"}, "gauges.coupler_mid.position"),
    (CR, {"gauges.coupler_mid.position": "5"}, "gauges.coupler_mid.position"),
    (CR, {"gauges.coupler_mid.position": "5 deg"}, "gauges.coupler_mid.position"),
    (CR, {"gauges.coupler_mid.face": "left"}, "gauges.coupler_mid.face"),
    (CR, {"gauges.coupler_mid.face": "TOP"}, "gauges.coupler_mid.face"),
    (CR, {"gauges.coupler_mid": "coupler"}, "gauges.coupler_mid"),
    (CR, {"gauges.coupler_mid": {}}, "gauges.coupler_mid.link"),
    (SC, {"gauges.coupler_mid.link": "rocker"}, "gauges.coupler_mid.link"),
    (WS, {"gauges": {"g": {"link": "coupler", "position": "50 in"}}}, "gauges.g.position"),
    (WS, {"gauges": {"g": {"link": "crank", "position": "1 in"}}}, "gauges.g.link"),
]


@pytest.mark.parametrize("name, overrides, key", GAUGES)
def test_gauges(name, overrides, key):
    refuses(name, overrides, key)


# -- drive ----------------------------------------------------------------------------------------------
DRIVE = [
    (CR, {"drive.speed": "1e7 rpm"}, "drive.speed"),                    # was named materials.aluminium.E
    (CR, {"drive.mode": "free"}, "drive.mode"),
    (CR, {"drive.mode": "motor", "motor": None}, "drive.mode"),
    (CR, {"drive.rotation": "clockwise"}, "drive.rotation"),
    (CR, {"drive.speed": None}, "drive.speed"),                  # was a scenario with no speed
    (CR, {"drive.speed": "0 rpm"}, "drive.speed"),               # was named solver.tmm.step
    (CR, {"drive.speed": "-373 rpm"}, "drive.speed"),
    (CR, {"drive.speed": "373 m/s"}, "drive.speed"),
]


@pytest.mark.parametrize("name, overrides, key", DRIVE)
def test_drive(name, overrides, key):
    refuses(name, overrides, key)


# -- solver, coupling and output settings ---------------------------------------------------------------
SOLVER = [
    (CR, {"solver.tmm.step": "0 deg"}, "solver.tmm.step"),
    (CR, {"solver.tmm.step": "-1 deg"}, "solver.tmm.step"),
    (CR, {"solver.tmm.step": "1e3 s"}, "solver.tmm.step"),          # was accepted: longer than a revolution
    (CR, {"solver.tmm.step": "400 deg"}, "solver.tmm.step"),        # was accepted
    (CR, {"solver.exudyn.step": "1 s"}, "solver.exudyn.step"),      # was accepted
    (CR, {"coupling.macro_step": "720 deg"}, "coupling.macro_step"),
    (CR, {"solver.tmm.integrator": "euler"}, "solver.tmm.integrator"),
    (CR, {"solver.tmm.segments": -1}, "solver.tmm.segments"),
    (CR, {"solver.tmm.segments": 0}, "solver.tmm.segments"),
    (CR, {"solver.tmm.segments": "8"}, "solver.tmm.segments"),
    (CR, {"solver.tmm.segments": 8.0}, "solver.tmm.segments"),
    (CR, {"solver.tmm.beam_column": "yes"}, "solver.tmm.beam_column"),
    (CR, {"solver.tmm.start": "moving"}, "solver.tmm.start"),
    (CR, {"solver.tmm.axial_force": "iterated"}, "solver.tmm.axial_force"),
    (CR, {"solver.tmm.axial_force": "quasi_static", "solver.tmm.beam_column": False}, "solver.tmm.axial_force"),
    (CR, {"solver.tmm.modes": 4}, "solver.tmm.modes"),
    (CR, {"solver.tmm.model": "reduced", "solver.tmm.modes": 0}, "solver.tmm.modes"),
    (CR, {"solver.tmm.model": "tiny"}, "solver.tmm.model"),
    (CR, {"solver.tmm.coupling": {"coriolis": "on"}}, "solver.tmm.coupling.coriolis"),
    (CR, {"solver.tmm.coupling": {"gyro": True}}, "solver.tmm.coupling.gyro"),
    (CR, {"solver.tmm.coupling": True}, "solver.tmm.coupling"),
    (CR, {"solver.exudyn.elements": 0}, "solver.exudyn.elements"),
    (CR, {"solver.exudyn.step": "0 s"}, "solver.exudyn.step"),
    (CR, {"solver.exudyn.spectral_radius": 1.5}, "solver.exudyn.spectral_radius"),
    (CR, {"solver.exudyn.spectral_radius": "0.9"}, "solver.exudyn.spectral_radius"),
    (CR, {"solver.exudyn.newton_tolerance": 0}, "solver.exudyn.newton_tolerance"),
    (CR, {"solver.mujoco.servo_frequency": "-5 Hz"}, "solver.mujoco.servo_frequency"),
    (CR, {"solver.mujoco.solref_factor": 0}, "solver.mujoco.solref_factor"),
    (CR, {"solver.mujoco.solimp": 2}, "solver.mujoco.solimp"),                       # was accepted
    (CR, {"solver.mujoco.solimp": -0.5}, "solver.mujoco.solimp"),                    # was accepted
    (CR, {"coupling.macro_step": "0 deg"}, "coupling.macro_step"),
    (CR, {"coupling.scheme": "newton"}, "coupling.scheme"),
    (CR, {"coupling.extrapolation": "cubic"}, "coupling.extrapolation"),
    (CR, {"coupling.max_iterations": 0}, "coupling.max_iterations"),
    (CR, {"coupling.tolerance": -1}, "coupling.tolerance"),
    (CR, {"coupling.start": "moving"}, "coupling.start"),
    (CR, {"coupling.interface_jacobian": 1}, "coupling.interface_jacobian"),
    (CR, {"output.revolutions": 0}, "output.revolutions"),
    (CR, {"output.revolutions": "2"}, "output.revolutions"),
    (CR, {"output.revolutions": 1e30}, "output.revolutions"),
    (CR, {"output.max_revolutions": -3}, "output.max_revolutions"),
    (CR, {"output.engines": []}, "output.engines"),
    (CR, {"output.engines": ["ansys"]}, "output.engines"),
    (CR, {"output.engines": "tmm"}, "output.engines"),
    (CR, {"output.engines": ["tmm", "tmm"]}, "output.engines"),                      # was accepted
    (CR, {"output.steady_tolerance": "0 %"}, "output.steady_tolerance"),
]


@pytest.mark.parametrize("name, overrides, key", SOLVER)
def test_solver(name, overrides, key):
    refuses(name, overrides, key)


# -- motor ----------------------------------------------------------------------------------------------
MOTOR = [
    (CR, {"motor.rated_torque": "1 N*m"}, "motor.rated_torque"),
    (CR, {"motor.rated_power": "-1 hp"}, "motor.rated_power"),
    (CR, {"motor.rated_power": "0.5 rpm"}, "motor.rated_power"),
    (CR, {"motor.rated_power": None}, "motor.rated_power"),
    (CR, {"motor.rated_speed": "0 rpm"}, "motor.rated_speed"),
    (CR, {"motor.rated_voltage": "90"}, "motor.rated_voltage"),
    (CR, {"motor.gear_ratio": 0}, "motor.gear_ratio"),
    (CR, {"motor.gear_ratio": "4"}, "motor.gear_ratio"),
    (CR, {"motor.gear_ratio": -4}, "motor.gear_ratio"),
    (CR, {"motor.efficiency": "150 %"}, "motor.efficiency"),            # was named motor.rated_power
    (CR, {"motor.efficiency": 1.5}, "motor.efficiency"),
    (CR, {"motor.copper_loss_share": 2}, "motor.copper_loss_share"),    # was named 'motor'
    (CR, {"motor.coulomb_share": 2}, "motor.coulomb_share"),            # was named 'motor'
    (CR, {"motor.resistance": "0 ohm"}, "motor.resistance"),
    (CR, {"motor.resistance": "1 V"}, "motor.resistance"),
    (CR, {"motor.inductance": "-1 H"}, "motor.inductance"),
    (CR, {"motor.rotor_inertia": "-1 kg*m^2"}, "motor.rotor_inertia"),
    (CR, {"motor.flywheels": 5}, "motor.flywheels"),
    (CR, {"motor.flywheels[0].diameter": "0 in"}, "motor.flywheels[0].diameter"),
    (CR, {"motor.flywheels[0].count": 0}, "motor.flywheels[0].count"),
    (CR, {"motor.flywheels[0].count": 1.5}, "motor.flywheels[0].count"),
    (CR, {"motor.flywheels[0].density": "1 kg"}, "motor.flywheels[0].density"),
    (CR, {"motor.flywheels[0].thickness": None}, "motor.flywheels[0].thickness"),
    (CR, {"motor.flywheels[1].diameter": "1e19 m"}, "motor.flywheels[1]"),                 # was accepted
    (CR, {"motor.flywheel_inertia": "1 kg*m^2"}, "motor.flywheels"),
    (CR, {"motor.controller": "fast"}, "motor.controller"),
    (CR, {"motor.controller.bandwidth": "0 Hz"}, "motor.controller.bandwidth"),
    (CR, {"motor.controller.kp": "1 V*s/rad"}, "motor.controller"),
    (CR, {"motor.controller.current_limit": "0 A"}, "motor.controller.current_limit"),
    (CR, {"motor.setpoint": {"profile": "sine"}}, "motor.setpoint.profile"),
    (CR, {"motor.setpoint": {"duration": "-1 s"}}, "motor.setpoint.duration"),
    (CR, {"motor.shaft_stiffness": "0 N*m/rad"}, "motor.shaft_stiffness"),
    (CR, {"motor.shaft_damping": "-1 N*m*s/rad"}, "motor.shaft_damping"),
    (CR, {"motor.reversible": "no"}, "motor.reversible"),
    (CR, {"motor.supply_voltage": "0 V"}, "motor.supply_voltage"),
    (CR, {"motor": "0.5 hp"}, "motor"),
    (CR, {"motor.electrical_time_constant": "0 s"}, "motor.electrical_time_constant"),
    (CR, {"motor.rotor_inertia_per_power": "1 kg"}, "motor.rotor_inertia_per_power"),
    (CR, {"motor.controller.bandwidth": "1e9 Hz"}, "motor.controller.bandwidth"),          # was accepted
    (CR, {"motor.rated_voltage": "0.001 V"}, "motor.rated_voltage"),                      # was accepted
    (CR, {"motor.rated_power": "1e-25 W"}, "motor.rated_power"),                          # was accepted
]


@pytest.mark.parametrize("name, overrides, key", MOTOR)
def test_motor(name, overrides, key):
    refuses(name, overrides, key)


# -- extends: files near the scenario, never echoed ----------------------------------------------------
def _write(path: Path, text: str, encoding="utf-8") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding=encoding)
    return path


_SPEED = '[scenario]\nname = "mine"\n[drive]\nspeed = "100 rpm"\n'
EXTENDS = [
    # (files to write {relative path: text}, extends value as TOML, the words the message must hold)
    ({}, "5", "key 'extends'"),
    ({}, '""', "key 'extends'"),
    ({}, '["base/fe_crank_rocker"]', "key 'extends'"),
    ({}, '"base/nope"', "key 'extends'"),
    ({}, '"base/fe_crank_rocker.json"', "key 'extends'"),
    ({}, '"../../../other/base"', "key 'extends'"),
    ({"lab/base/folder.toml/x": ""}, '"base/folder"', "key 'extends'"),
    ({"lab/base/loop.toml": 'extends = "../speeds/mine"\n'}, '"../base/loop"', "key 'extends'"),
    ({"lab/base/typo.toml": 'extends = "base/fe_crank_rocker"\n[linkage]\ngrund = "1 in"\n'}, '"../base/typo"',
     "key 'linkage.grund'"),
    ({"lab/base/bad.toml": "[linkage\nsecret = 1\n"}, '"../base/bad"', "bad.toml"),
    ({"lab/base/u16.toml": ("[linkage]\n", "utf-16")}, '"../base/u16"', "u16.toml"),
    ({"lab/base/big.toml": "# " + "x" * 1_100_000 + "\n"}, '"../base/big"', "big.toml"),
]


@pytest.mark.parametrize("files, extends, words", EXTENDS)
def test_extends(tmp_path, files, extends, words):
    for rel, text in files.items():
        text, enc = text if isinstance(text, tuple) else (text, "utf-8")
        if rel.endswith("/x"):
            (tmp_path / rel).parent.mkdir(parents=True)
            continue
        _write(tmp_path / rel, text, enc)
    path = _write(tmp_path / "lab" / "speeds" / "mine.toml", f"extends = {extends}\n" + _SPEED)
    with pytest.raises(ScenarioError) as err:
        load(path)
    msg = str(err.value)
    assert words in msg, msg
    assert "secret" not in msg and "xxxx" not in msg


# -- records: the sidecar's keys and the CSV's cells ------------------------------------------------------
def _set(path, value):
    def edit(d):
        node, parts = d, path.split(".")
        for p in parts[:-1]:
            node = node[p]
        if value is None:
            node.pop(parts[-1])
        else:
            node[parts[-1]] = value
    return edit


def _sub(old, new):
    return lambda text: text.replace(old, new, 1)


P, H, V = "fe_table1_peaks", "fe_table2_373rpm", "fe_natural_frequencies"
_ROW = "95,rocker_mid,+,bending,80.788,uin/in"
RECORDS = [
    (P, _set("record.format", "graph"), None, "record.format"),
    (P, _set("record.kind", "guess"), None, "record.kind"),
    (P, _set("record.name", None), None, "record.name"),
    (P, _set("record.name", 5), None, "record.name"),                         # was accepted
    (P, _set("record.speed", "373"), None, "record.speed"),
    (P, _set("record.speed", "373 in"), None, "record.speed"),
    (P, _set("record.rig", 5), None, "record.rig"),                           # was accepted
    (P, _set("record", "x"), None, "[record]"),
    (P, _set("provenance", None), None, "[provenance]"),
    (P, _set("provenance", "thesis"), None, "[provenance]"),
    (P, _set("provenance.source", 5), None, "provenance.source"),             # was accepted
    (P, _set("record.sign_convention", 5), None, "record.sign_convention"),   # was accepted
    (H, _set("index", None), None, "[index]"),
    (H, _set("index.unit", "rad"), None, "index.unit"),
    (H, _set("index.column", "angle"), None, "column 'angle'"),
    (H, _set("index.column", ["a"]), None, "index.column"),                   # was a message naming ['a']
    (H, _set("channels", None), None, "[channels"),
    (H, _set("channels", 5), None, "[channels"),
    (H, _set("channels.coupler_uin_in", "bending"), None, "channels.coupler_uin_in"),     # was an AttributeError
    (H, _set("channels.coupler_uin_in.quantity", "torque"), None, "channels.coupler_uin_in.quantity"),
    (H, _set("channels.coupler_uin_in.unit", "psi"), None, "channels.coupler_uin_in.unit"),
    (H, _set("channels.coupler_uin_in.unit", 5), None, "channels.coupler_uin_in.unit"),
    (H, _set("channels.coupler_uin_in.unit", None), None, "channels.coupler_uin_in.unit"),  # was read as strain
    (H, _set("channels.coupler_uin_in.face", "left"), None, "channels.coupler_uin_in.face"),
    (H, _set("channels.coupler_uin_in.gauge", 5), None, "channels.coupler_uin_in.gauge"),  # was accepted
    (H, _set("channels.coupler_uin_in.calibration", "x"), None, "channels.coupler_uin_in.calibration"),
    (H, _set("channels.coupler_uin_in.quantity", "raw"), None, "channels.coupler_uin_in.calibration"),
    (H, _set("channels.nope", {"quantity": "bending", "unit": "ue"}), None, "column 'nope'"),
    (H, _set("acquisition", {"trigger_channel": "nope"}), None, "acquisition.trigger_channel"),
    (H, _set("acquisition", 5), None, "acquisition"),                                       # was a TypeError
    (H, _set("acquisition", {"trigger_channel": ["x"]}), None, "acquisition.trigger_channel"),  # was a TypeError
    (H, _set("acquisition", {"trigger_channel": "coupler_uin_in"}), None,      # a gauge as the trigger: was accepted
     "key 'acquisition.trigger_channel' = 'coupler_uin_in': channel of quantity 'bending'"),
    (H, None, _sub("8,197.584", "8,abc"), "column 'input_uin_in'"),
    (H, None, _sub("8,197.584", "0,197.584"), "column 'crank_angle_deg'"),
    (H, None, _sub("8,197.584", "8,nan"), "column 'input_uin_in'"),
    (H, None, _sub("8,197.584,", "8,"), "cells, the header has"),
    (P, None, _sub(_ROW, "95,rocker_mid,*,bending,80.788,uin/in"), "column 'peak'"),
    (P, None, _sub(_ROW, "95,rocker_mid,+,bending,80.788,psi"), "column 'unit'"),
    (P, None, _sub(_ROW, "95,rocker_mid,+,torsion,80.788,uin/in"), "column 'quantity'"),
    (P, None, _sub(_ROW, "fast,rocker_mid,+,bending,80.788,uin/in"), "column 'rpm'"),
    (P, None, _sub(_ROW, "95,rocker_mid,+,bending,inf,uin/in"), "column 'value'"),
    (P, None, _sub(_ROW, "95,rocker_mid,+,bending,1e400,uin/in"), "column 'value'"),
    (P, None, _sub(_ROW, "-95,rocker_mid,+,bending,80.788,uin/in"), "column 'rpm'"),     # was accepted
    (P, None, _sub(_ROW, "95,,+,bending,80.788,uin/in"), "column 'gauge'"),              # was accepted
    (P, None, _sub("rpm,gauge", "speed,gauge"), "column 'rpm'"),
    (P, None, lambda text: "", "empty file"),
    (V, None, _sub("125.0,Hz", "abc,Hz"), "column 'value'"),
    (V, None, _sub("quantity,link", "quantity,member"), "column 'link'"),
]


@pytest.mark.parametrize("stem, sidecar, data, words", RECORDS)
def test_records(tmp_path, stem, sidecar, data, words):
    meta = tomllib.loads((RECORD_DIR / f"{stem}.toml").read_text())
    if sidecar:
        sidecar(meta)
    (tmp_path / "r.toml").write_text(tomli_w.dumps(meta))
    text = (RECORD_DIR / f"{stem}.csv").read_text()
    (tmp_path / "r.csv").write_text(data(text) if data else text)
    with pytest.raises(RecordError) as err:
        load_record(tmp_path / "r.toml")
    assert words in str(err.value) and "r." in str(err.value), str(err.value)


# -- the command line: exit 2 and one `error:` line naming the flag, before anything runs ------------------
_RUN = ["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "0.05"]
_SWEEP = ["sweep", "crank_rocker_373rpm", "--no-campbell", "--no-record"]
CLI = [
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "inf"], "--revolutions"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "nan"], "--revolutions"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "0"], "--revolutions"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "-1"], "--revolutions"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "abc"], "--revolutions"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record", "--revolutions", "1e12"], "GB"),
    (_RUN + ["--exaggeration", "-2"], "--exaggeration"),
    (_RUN + ["--exaggeration", "inf"], "--exaggeration"),
    (_RUN + ["--linkage-fps", "0"], "--linkage-fps"),                   # was accepted
    (_RUN + ["--linkage-fps", "nan"], "--linkage-fps"),                 # was accepted
    (_RUN + ["--linkage-fps", "-5"], "--linkage-fps"),                  # was accepted
    (_RUN + ["--viewer-timeout", "-1"], "--viewer-timeout"),            # was accepted with --no-record
    (_RUN + ["--max-hours", "0"], "--max-hours"),
    (_RUN + ["--max-hours", "-1"], "--max-hours"),
    (_RUN + ["--out", "held"], "holds another run"),
    (_RUN + ["--records", "nowhere"], "--records"),
    (_RUN + ["--records", "notdir"], "--records"),
    (_RUN + ["--drive", "sideways"], "--drive"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm,ansys", "--no-record"], "--engines"),
    (["run", "crank_rocker_373rpm", "--engines", ",,", "--no-record"], "--engines"),
    (["run", "crank_rocker_373rpm", "--engines", "tmm,tmm", "--no-record"], "--engines"),     # was accepted
    (["run", "no_such_scenario", "--no-record"], "no_such_scenario"),
    (["run", "exists.toml", "--no-record"], "exists.toml"),
    (["run", "bad.toml", "--no-record"], "bad.toml"),
    (["run", "../../etc/passwd", "--no-record"], "passwd"),
    (["run", "empty", "--no-record"], "empty"),
    (_SWEEP + ["--rpm", "100:400:0"], "--rpm"),
    (_SWEEP + ["--rpm", "100:400:-5"], "--rpm"),
    (_SWEEP + ["--rpm", "abc"], "--rpm"),
    (_SWEEP + ["--rpm", ""], "--rpm"),
    (_SWEEP + ["--rpm", "nan"], "--rpm"),                               # was a sweep ending in a matplotlib error
    (_SWEEP + ["--rpm", "inf"], "--rpm"),
    (_SWEEP + ["--rpm", "-100"], "--rpm"),
    (_SWEEP + ["--rpm", "0"], "--rpm"),
    (_SWEEP + ["--rpm", "1:1e9:1"], "--rpm"),                           # was gigabytes, then the OOM killer
    (_SWEEP + ["--rpm", "100", "--engines", "nope"], "--engines"),
    (_SWEEP + ["--rpm", "100", "--workers", "0"], "--workers"),          # was accepted
    (_SWEEP + ["--rpm", "100", "--workers", "-2"], "--workers"),         # was refused after the sweep started
    (_SWEEP + ["--rpm", "100", "--revolutions", "nan"], "--revolutions"),
    (_SWEEP + ["--rpm", "100", "--revolutions", "-1"], "--revolutions"),
    (_SWEEP + ["--rpm", "100", "--method", "guess"], "--method"),
    (["uncertainty", "crank_rocker_373rpm", "--samples", "0"], "--samples"),
    (["uncertainty", "crank_rocker_373rpm", "--samples", "-3"], "--samples"),
    (["uncertainty", "crank_rocker_373rpm", "--trajectories", "0"], "--trajectories"),
    (["uncertainty", "crank_rocker_373rpm", "--samples", "100000000"], "--samples"),   # was the OOM killer
    (["uncertainty", "crank_rocker_373rpm", "--trajectories", "10000000"], "--trajectories"),
    (["uncertainty", "alexander_lawrence_400rpm"], "uncertainty"),
    (["compare", "nowhere"], "nowhere"),
    (["compare", "empty"], "summary.json"),
    (["compare", "listsum"], "summary.json"),
    (["compare", "badjson"], "summary.json"),
    (["compare", "nosc"], "summary.json"),
    (["compare", "notdir"], "notdir"),
    (["new", "../evil"], "name"),
    (["new", "a b"], "name"),
    (["new", ""], "name"),
    (["new", "exists"], "exists.toml"),
    (["new", "ok1", "--like", "no_such"], "no_such"),
    (["new", "ok2", "--out", "notdir"], "notdir"),
    (["identify", "crank_rocker_241rpm", "--validate", "nope"], "nope"),
    # Issue 32: every subcommand's cost estimated before any work starts, named by its option.
    (_SWEEP + ["--rpm", "100,200", "--method", "march", "--revolutions", "1e9"], "--revolutions"),  # ran unbounded
    (_SWEEP + ["--rpm", "100", "--max-hours", "0"], "--max-hours"),
    (["uncertainty", "crank_rocker_373rpm", "--samples", "5000", "--max-hours", "0.01"], "--samples"),
    (["uncertainty", "crank_rocker_373rpm", "--max-hours", "-1"], "--max-hours"),
    (["identify", "crank_rocker_241rpm", "--starts", "100000000"], "--starts"),       # was a MemoryError
    (["identify", "crank_rocker_241rpm", "--max-hours", "nan"], "--max-hours"),
    (["run", "gauges10k.toml", "--engines", "tmm", "--no-record"], "10002 gauges"),   # was 6.29 TiB asked for
    (["synthesize", "--case", "III"], "--case"),
]


@pytest.fixture
def cli_dir(tmp_path, monkeypatch):
    """A working folder with the files the command-line cases point at."""
    for name, text in (("held/summary.json", '{"scenario": "x", "status": "completed"}'),
                       ("listsum/summary.json", "[1, 2]"), ("badjson/summary.json", "{"),
                       ("nosc/summary.json", '{"status": 5}'), ("exists.toml", "x"), ("bad.toml", "[scenario\n"),
                       ("notdir", "x")):
        _write(tmp_path / name, text)
    (tmp_path / "empty").mkdir()
    gauges = "".join(f'[gauges.g{i}]\nlink = "coupler"\nposition = "5 in"\n' for i in range(10_000))
    _write(tmp_path / "gauges10k.toml", 'extends = "crank_rocker_373rpm"\n[scenario]\nname = "g10k"\n' + gauges)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("argv, flag", CLI)
def test_cli(cli_dir, capsys, argv, flag):
    try:
        code = main(argv)
    except SystemExit as exc:               # argparse: usage, then one `cosim ...: error:` line
        code = exc.code
    err = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert code == 2 and len(err) == 1 and flag in err[0], (code, err)
    assert not (cli_dir / "logs").exists()


def test_the_corpus_is_large_enough():
    families = (KEYS, UNITS, GEOMETRY, MATERIALS, DAMPING, GAUGES, DRIVE, SOLVER, MOTOR, EXTENDS, RECORDS, CLI)
    assert sum(len(f) for f in families) >= 100 and all(len(f) >= 7 for f in families)
