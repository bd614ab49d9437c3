"""FMI 2.0 co-simulation: the bench's models as FMUs for other masters, and FMUs as drives here.

Export (:mod:`cosim.fmi.export`): one engine on one scenario (:mod:`cosim.fmi.linkage_slave`) or
the scenario's DC motor (:mod:`cosim.fmi.motor_slave`) packaged by PythonFMU. Import
(:mod:`cosim.fmi.drive`): an FMU that takes the crank speed and returns the drive torque drives
the master in place of the bench's own motor (``[drive] type = "fmu"``, :mod:`cosim.fmi.drive_spec`).

Owns: nothing itself (the package's modules do). Boundaries: PythonFMU and FMPy are imported only
by the modules that need them, never when cosim is imported.
"""
