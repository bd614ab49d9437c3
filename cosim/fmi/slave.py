"""What every FMU the bench exports shares: its scenario and settings read from the FMU's
resources, and real variables that carry their units into the model description.

An FMU built by PythonFMU runs this code inside the importing process, with the Python
environment that has ``pythonfmu`` installed: the model class imports cosim and tmm_core from
that environment, the scenario travels in the FMU (resources/scenario.toml, the scenario with its
bases merged) so the FMU does not depend on the scenario files.

Units: FMI unit names (``"N.m"``, ``"rad/s"``) with their SI base-unit exponents, written as
``<UnitDefinitions>`` (pint gives the exponents, :mod:`cosim.units`).

Owns: ``BenchSlave`` (resources, unit-tagged variables, the XML with units), ``FMI_UNITS``.
Boundaries: no engine or motor code (the two slaves).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real

from ..scenario import load
from ..units import UREG

#: Resource files of an exported FMU.
SCENARIO_FILE = "scenario.toml"
CONFIG_FILE = "bench_fmu.json"

#: FMI unit name -> (pint spelling, exponent of rad). pint counts the radian as 1, so the
#: angle's exponent is kept here (FMI's BaseUnit has a ``rad`` exponent of its own).
FMI_UNITS = {"rad": ("rad", 1), "rad/s": ("rad/s", 1), "rad/s2": ("rad/s^2", 1), "N.m": ("N*m", 0),
             "kg.m2": ("kg*m^2", 0), "m": ("m", 0), "s": ("s", 0), "A": ("A", 0), "V": ("V", 0), "1": ("dimensionless", 0)}
_BASE = {"[mass]": "kg", "[length]": "m", "[time]": "s", "[current]": "A", "[temperature]": "K"}

CAUSALITY = {"input": Fmi2Causality.input, "output": Fmi2Causality.output,
             "parameter": Fmi2Causality.parameter, "calculatedParameter": Fmi2Causality.calculatedParameter}


def base_unit(fmi_unit: str) -> dict:
    """The ``<BaseUnit>`` attributes of an FMI unit name of :data:`FMI_UNITS` (SI exponents)."""
    spelling, rad = FMI_UNITS[fmi_unit]
    dims = UREG.Quantity(1.0, spelling).dimensionality
    attrs = {_BASE[d]: str(int(p)) for d, p in dims.items() if p}
    if rad:
        attrs["rad"] = str(rad)
    return attrs


class BenchSlave(Fmi2Slave):
    """An FMU of the bench: ``self.scenario`` and ``self.config`` from the resources, ``self.values``
    the variables' values (SI, the unit named with each variable)."""

    author = "flexlink-bench"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        res = Path(self.resources)
        self.config = json.loads((res / CONFIG_FILE).read_text())
        self.scenario = load(res / SCENARIO_FILE)
        self.values, self.units = {}, {}
        self.t0 = 0.0

    def add(self, name: str, unit: str, causality: str, start: float = 0.0, description: str = "") -> None:
        """Register a real variable ``name`` [``unit``]. Parameters are fixed (set before the
        initialisation); calculated parameters are read-only facts of the scenario."""
        self.values[name] = float(start)
        self.units[name] = unit
        kw = {"causality": CAUSALITY[causality], "description": description or None,
              "getter": lambda: self.values[name]}
        if causality == "parameter":
            kw.update(variability=Fmi2Variability.fixed, initial=Fmi2Initial.exact)
        elif causality == "calculatedParameter":
            kw.update(variability=Fmi2Variability.fixed, initial=Fmi2Initial.calculated)
        else:
            kw.update(variability=Fmi2Variability.continuous)
        if causality in ("input", "parameter"):
            kw["setter"] = lambda v: self.values.__setitem__(name, float(v))
        self.register_variable(Real(name, start=float(start) if causality in ("input", "parameter") else None, **kw),
                               nested=False)

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.t0 = float(start_time)

    def to_xml(self, model_options: dict = dict()) -> Element:
        """PythonFMU's model description with a ``unit`` on every real and the units defined."""
        root = super().to_xml(model_options)
        for sv in root.iter("ScalarVariable"):
            real = sv.find("Real")
            if real is not None and sv.get("name") in self.units:
                real.set("unit", self.units[sv.get("name")])
        defs = Element("UnitDefinitions")
        for unit in sorted(set(self.units.values())):
            SubElement(SubElement(defs, "Unit", name=unit), "BaseUnit", base_unit(unit))
        # The schema's order: CoSimulation, UnitDefinitions, ... (after the CoSimulation element).
        index = list(root).index(root.find("CoSimulation")) + 1
        root.insert(index, defs)
        # Outputs and calculated parameters are computed in the initialisation: FMI 2.0 lists
        # them as initial unknowns (dependencies not given: on every known).
        unknowns = Element("InitialUnknowns")
        for i, sv in enumerate(root.find("ModelVariables"), start=1):
            if sv.get("causality") in ("output", "calculatedParameter"):
                SubElement(unknowns, "Unknown", index=str(i))
        if len(unknowns):
            root.find("ModelStructure").append(unknowns)
        return root

    def _get_fmu_state(self):
        return {"values": dict(self.values), "model": self.model_state()}

    def _set_fmu_state(self, state):
        self.values.update(state["values"])
        self.set_model_state(state["model"])

    def model_state(self):
        """The model's own state for fmi2GetFMUstate (kept in memory, not serialised)."""
        raise NotImplementedError

    def set_model_state(self, token) -> None:
        raise NotImplementedError


def finite(value: float, name: str) -> float:
    """``value`` if finite, else a ValueError naming the variable (an FMU's step then fails)."""
    if not math.isfinite(value):
        raise ValueError(f"{name} is not finite ({value!r})")
    return value
