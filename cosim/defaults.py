"""Defaults the command line states in its help, kept in a module that imports nothing, so that
``cosim --help`` does not load the modules that use them.

Owns: :data:`MAX_HOURS` (the work limit of ``--max-hours``) and :data:`SYNTHESIS_LIKE` (the
scenario a synthesized linkage borrows its sections, materials and solvers from). Boundaries:
constants only.
"""

#: A run whose estimated wall time exceeds this [h] is refused before anything is allocated
#: (``RunOptions.max_hours``, ``cosim run --max-hours``; cosim.run_guards).
MAX_HOURS = 2.0

#: ``cosim synthesize --scenario-out``: the scenario whose sections, materials, gauges, drive and
#: solvers a synthesized linkage keeps unless ``--like`` names another (cosim.synthesis).
SYNTHESIS_LIKE = "crank_rocker_373rpm"
