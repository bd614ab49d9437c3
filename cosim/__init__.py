"""Co-simulation bench: scenarios, engines (TMM, exudyn, MuJoCo), motor, records, rerun streaming."""
__version__ = "0.1.0"
