"""Co-simulation bench: scenarios, engines (TMM, exudyn, MuJoCo), motor, records, rerun streaming.

``cosim.load_run(folder)`` loads a run folder (traces as a long pandas DataFrame, the summary);
see :mod:`cosim.results`.

Owns: the package's public names (load, load_run, run_scenario). Boundaries: it imports nothing
heavy at import time (engines load lazily).
"""
__version__ = "0.1.0"
__all__ = ["__version__", "load_run", "RunData"]


def __getattr__(name):
    # Imported on first use: `cosim` on the command line should not pay for pandas.
    if name in ("load_run", "RunData"):
        from . import results
        return getattr(results, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
