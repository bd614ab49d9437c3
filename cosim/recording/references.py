"""Records drawn beside the engines: checked and named when they are given, placed on the run's
timelines when the recording closes (:func:`cosim.alignment` functions, in the writer).

Pure numpy: the checks run in the run's own process, so a bad record is refused there.

Owns: records drawn beside the engines. Boundaries: no scoring.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .layout import RECORD_COLORS, part, shades

COMPONENT_ROOTS = {"bending": "strain", "axial": "axial_strain"}    # /records/<root>/<gauge>/<label>


@dataclass
class Reference:
    """One component (bending or axial) of a record for a gauge, values in microstrain."""

    entity: str
    names: list
    colors: list
    t: np.ndarray | None               # a history over time [s]
    angle: np.ndarray | None           # a history over one revolution [rad]
    values: np.ndarray                 # (k, m) for a history, (m,) constants


def make_references(gauge: str, label: str, t=None, angle=None, bending_ue=None, axial_ue=None,
                    kind: str = "measurement", index: int = 0) -> list:
    """The :class:`Reference` of each component given (see ``Recorder.log_reference``); errors
    name the argument."""
    if t is not None and angle is not None:
        raise ValueError("log_reference: give t or angle, not both")
    comps = [(c, v) for c, v in (("bending", bending_ue), ("axial", axial_ue)) if v is not None]
    if not comps:
        raise ValueError(f"log_reference({gauge!r}, {label!r}): give bending_ue and/or axial_ue")
    color = RECORD_COLORS[index % len(RECORD_COLORS)]
    how = f"({kind.replace('_', ' ')})"

    def words(comp, *tags):
        # Short legend entries: the bending plot is per gauge, the axial plot holds every gauge.
        return " ".join(filter(None, (label, gauge if comp == "axial" else "", "axial" if comp == "axial" else "",
                                      *tags, how))) + " [µε]"
    x = None
    if t is not None or angle is not None:
        x = np.asarray(t if t is not None else angle, dtype=float).ravel()
    refs = []
    for comp, v in comps:
        entity = f"/records/{COMPONENT_ROOTS[comp]}/{part(gauge)}/{part(label)}"
        if x is None:                                  # constants: horizontal lines across the run
            v = np.atleast_1d(np.asarray(v, dtype=float)).ravel()
            tags = ["+peak", "-peak"] if len(v) == 2 else ([""] if len(v) == 1 else
                                                           [f"#{i + 1}" for i in range(len(v))])
            names = [words(comp, tag) for tag in tags]
            refs.append(Reference(entity, names, shades(color, len(names)), None, None, v))
            continue
        c = np.asarray(v, dtype=float).ravel()
        if c.shape != x.shape:
            raise ValueError(f"log_reference({gauge!r}, {label!r}): {comp}_ue has {c.size} values, "
                             f"{'t' if t is not None else 'angle'} has {x.size}")
        refs.append(Reference(entity, [words(comp)], [color],
                              x if t is not None else None, x if angle is not None else None, c[:, None]))
    return refs
