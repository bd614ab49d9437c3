"""Engines behind one protocol (:mod:`cosim.engines.base`): 'tmm', 'exudyn', 'mujoco'.

The reference engines import their libraries lazily, so a missing or broken exudyn or MuJoCo
install only disables that engine, with a message saying how to fix it.

Owns: the engine registry (``make_engine``, ``ENGINES``) and lazy engine imports. Boundaries: no
engine code.
"""
from __future__ import annotations

from tmm_core.errors import InputError

from ..interrupts import caused_by_interrupt
from .base import DriveInput, Engine, EngineError, EngineOutput, EngineRun, EngineUnavailable

ENGINES = ("tmm", "exudyn", "mujoco")

#: What each engine models, as the console and the summary say it: the two flexible models
#: predict strain from the links' elastic deflection; the rigid one has no deflection, so its
#: "strains" are those of the rigid-body loads acting on a static beam (why it can look closest
#: to a record that the flexible models overshoot, or far from them near a resonance).
MODELS = {"tmm": "flexible: transfer-matrix beams",
          "exudyn": "flexible: ANCF beam elements",
          "mujoco": "rigid bodies, quasi-static strain"}


def check_engine_names(names) -> None:
    """Refuse a name that is not one of :data:`ENGINES` (:class:`tmm_core.errors.InputError`,
    naming it and the engines there are), before anything runs."""
    for name in names:
        if name not in ENGINES:
            raise InputError(f"unknown engine {name!r}; choose from {', '.join(ENGINES)}")


def is_rigid(engine: str) -> bool:
    """Whether the engine's model has no elastic deflection (:data:`MODELS`)."""
    return MODELS.get(engine, "").startswith("rigid")


def make_engine(name: str, *, backend: str | None = None) -> Engine:
    """A fresh engine by name; raises :class:`EngineUnavailable` if its library cannot be imported.
    ``backend``: the transfer-matrix engine's computing backend (:mod:`tmm_core.backend`:
    "compiled" or "numpy"; None, the default); another engine refuses one."""
    if backend is not None and name != "tmm":
        raise EngineError(f"engine {name!r} has no computing backend to choose (backend = {backend!r}); only 'tmm' has")
    if name == "tmm":
        from .tmm import TMMEngine
        return TMMEngine(backend=backend)
    if name == "exudyn":
        _require("exudyn", "exudyn>=1.13.6,<1.14")
        from .exudyn import ExudynEngine
        return ExudynEngine()
    if name == "mujoco":
        _require("mujoco", "mujoco>=4.0,<4.1")
        from .mujoco import MujocoEngine
        return MujocoEngine()
    raise EngineError(f"unknown engine {name!r}; choose from {', '.join(ENGINES)}")


def _require(module: str, spec: str) -> None:
    import importlib
    try:
        importlib.import_module(module)
    except Exception as exc:   # ImportError, or a broken binary wheel raising anything else
        if caused_by_interrupt(exc):
            raise KeyboardInterrupt(f"interrupted while importing {module}") from None
        raise EngineUnavailable(f"engine '{module}' is unavailable: importing {module} failed ({type(exc).__name__}: "
                                f"{exc}); install it with `pip install \"{spec}\"` (make test/run does)") from None


def available_engines() -> dict:
    """``{engine: None or the reason it is unavailable}``."""
    out = {}
    for name in ENGINES:
        try:
            if name != "tmm":
                _require(name, "")
            out[name] = None
        except EngineUnavailable as exc:
            out[name] = str(exc)
    return out
