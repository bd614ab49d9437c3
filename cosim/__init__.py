"""Co-simulation bench: scenarios, engines (TMM, exudyn, MuJoCo), motor, records, rerun streaming.

From a script, every name below is imported from ``cosim`` itself::

    import cosim
    sc = cosim.load("crank_rocker_373rpm")                 # a scenario (name, path); .with_overrides(...)
    data = cosim.run(sc, engines=["tmm"])                  # summary, traces (pandas DataFrame), folder
    points = cosim.sweep(sc, [200, 300, 373])              # peak strains against speed
    result = cosim.CoSimulation(sc, ("tmm",)).run(revolutions=2)   # the master, no files
    run = cosim.run_prescribed(cosim.make_engine("tmm"), sc, revolutions=1)   # one engine
    again = cosim.load_run(data.folder)                    # a run folder read back

Owns: the package's public names (:data:`__all__`). Boundaries: ``import cosim`` imports none of
them: each is imported on first use (the command line and a script that needs one name do not
pay for the engines, pandas or the scenario loader).
"""
import importlib

__version__ = "0.1.0"

#: Public name -> the module that owns it.
_OWNERS = {
    "load": "scenario", "Scenario": "scenario_types", "ScenarioError": "scenario_types",
    "run": "api", "sweep": "api", "SweepResult": "api",
    "CoSimulation": "master", "run_prescribed": "master",
    "make_engine": "engines", "available_engines": "engines",
    "load_run": "results", "RunData": "results",
    "run_scenario": "runs", "RunOptions": "runs",
}

__all__ = ["__version__", "load", "Scenario", "ScenarioError", "run", "sweep", "SweepResult", "CoSimulation",
           "run_prescribed", "make_engine", "available_engines", "load_run", "RunData", "run_scenario", "RunOptions"]


def __getattr__(name):
    # Imported on first use: `cosim --help` should not pay for the scenario loader or pandas.
    if name in _OWNERS:
        # Not cached in the module's namespace: the owner module is cached by the import system,
        # and the package's namespace stays what this file writes.
        return getattr(importlib.import_module(f".{_OWNERS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
