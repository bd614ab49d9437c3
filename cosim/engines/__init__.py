"""Engines behind one protocol (:mod:`cosim.engines.base`): 'tmm', 'exudyn', 'mujoco'.

The reference engines import their libraries lazily, so a missing or broken exudyn or MuJoCo
install only disables that engine, with a message saying how to fix it.

Owns: the engine registry (``make_engine``, ``ENGINES``) and lazy engine imports. Boundaries: no
engine code.
"""
from __future__ import annotations

from .base import DriveInput, Engine, EngineError, EngineOutput, EngineRun, EngineUnavailable, run_prescribed

ENGINES = ("tmm", "exudyn", "mujoco")


def make_engine(name: str) -> Engine:
    """A fresh engine by name; raises :class:`EngineUnavailable` if its library cannot be imported."""
    if name == "tmm":
        from .tmm import TMMEngine
        return TMMEngine()
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
