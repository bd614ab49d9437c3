"""The computing backend of a model, chosen once when the model is built.

``"compiled"``: the numba kernels of :mod:`tmm_core.compiled` (each the twin of the numpy module
of its name, held equal to it by a test); ``"numpy"``: the numpy reference. Every stage of a model
(the quasi-static start, the configurations, the march, the periodic solver, the reduced model)
reads the model's backend instead of deciding again. The default (None) is ``"compiled"`` when
numba is installed, else ``"numpy"``; asking for ``"compiled"`` without numba is refused, not
quietly run in numpy.

The compiled structure solve handles structures of joints and members; for others (springs,
plates, sliders) the compiled backend solves the structure in numpy: a property of the
structure, fixed when the model is built.

Owns: the backend names and the choice. Boundaries: no kernels (tmm_core.compiled).
"""
from __future__ import annotations

from .compiled.cache import AVAILABLE
from .errors import InputError

#: The backends a model can be built with.
BACKENDS = ("compiled", "numpy")


def choose_backend(backend: str | None) -> str:
    """The backend a model is built with: ``backend`` checked, or the default (None: compiled
    where numba is installed, else numpy). Raises :class:`InputError` for an unknown name, or for
    ``"compiled"`` without numba."""
    if backend is None:
        return "compiled" if AVAILABLE else "numpy"
    if backend not in BACKENDS:
        raise InputError(f"backend = {backend!r}: expected one of {', '.join(map(repr, BACKENDS))}")
    if backend == "compiled" and not AVAILABLE:
        raise InputError("backend = 'compiled' needs numba, which is not installed here: install it "
                         "(pip install numba) or build the model with backend = 'numpy'")
    return backend
