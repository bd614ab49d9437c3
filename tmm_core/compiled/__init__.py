"""The compiled backend of the transfer-matrix core (numba): each module is the compiled twin of
the numpy module of the same name in :mod:`tmm_core` (``compiled/structure.py`` mirrors
``structure.py``, ``compiled/time_step.py`` mirrors ``time_step.py``, ...), held equal to it by a
test (the pairs are listed in ``docs/architecture.md`` and ``tests/test_architecture.py``).

``dense`` holds the small dense algebra the numpy references leave to numpy and scipy (3x3
products and inverses, LU, LDL^T inertia) and the Stumpff series of :mod:`tmm_core.matrices`;
``binding`` compiles the kernels and binds them where their callers look them up (the one
registry); ``cache`` keys numba's on-disk cache by every compiled source; ``ahead`` compiles
kernels ahead in helper processes on a first run (``python -m tmm_core.compiled``); ``statics``
is the Python driver of the compiled structure solve (layout, threads, checks).

Importing this package imports no numba: kernels compile (or load from the cache) on first use.
"""
