"""A GIF of the linkage over the last revolution, every engine in its colour (``cosim run
--animation``): the same drawing as the recording's linkage view (:mod:`cosim.recording.linkage`),
for a slide or a report where no viewer is at hand. matplotlib and Pillow only.

Owns: ``linkage.gif``. Boundaries: no rerun.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files import clear_link
from tmm_core.revolution import last_revolution
from . import linkage as drawing
from .layout import STRAIGHT_COLOR, engine_color


def write_gif(path, runs: dict, stations: dict | None = None, exaggeration: float | None = None,
              frames: int = 48, fps: int = 12) -> Path:
    """``runs``: {engine: EngineRun} (nodes over time); ``stations``: {engine: {link: stations}};
    ``exaggeration``: None chooses it from the largest deformation, as the recording does.
    Returns the file written."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import animation
    from matplotlib import pyplot as plt

    picks = {}
    for engine, run in runs.items():
        if len(run.t) and run.nodes:
            idx = np.flatnonzero(last_revolution(run.crank_angle))
            picks[engine] = idx[np.linspace(0, len(idx) - 1, min(frames, len(idx))).round().astype(int)]
    if not picks:
        raise ValueError("no engine reported node positions to animate")
    stations = stations or {}
    if exaggeration is None:
        largest = max(drawing.largest_offset({k: v[i] for k, v in runs[e].nodes.items()}, stations.get(e))
                      for e, i in picks.items())
        longest = max(np.linalg.norm(v[0, -1] - v[0, 0]) for e in picks for v in runs[e].nodes.values())
        exaggeration = drawing.auto_factor(largest, longest)
    everything = np.concatenate([v[i].reshape(-1, 2) for e, i in picks.items() for v in runs[e].nodes.values()])
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    pad = 0.1 * float(np.max(hi - lo))
    fig, ax = plt.subplots(figsize=(6, 4.5), dpi=80)
    n = min(len(i) for i in picks.values())
    first = next(iter(picks))

    def draw(k):
        ax.clear()
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_title(f"deformation ×{exaggeration:g}; grey: straight links between the joints", fontsize=9)
        for engine, idx in picks.items():
            run, j = runs[engine], idx[k]
            straight, deformed, _ = drawing.frame({lk: v[j] for lk, v in run.nodes.items()}, stations.get(engine),
                                                  exaggeration)
            for s in straight:
                ax.plot(s[:, 0], s[:, 1], color=np.array(STRAIGHT_COLOR) / 255, lw=0.8)
            for i, d in enumerate(deformed):
                ax.plot(d[:, 0], d[:, 1], color=np.array(engine_color(engine, list(runs))) / 255, lw=2,
                        label=engine if i == 0 else None)
        ax.legend(loc="upper right", fontsize=8, frameon=False)
        angle = np.degrees(runs[first].crank_angle[picks[first][k]]) % 360
        ax.set_xlabel(f"x [m]   (crank angle {angle:.0f} deg)", fontsize=8)
    anim = animation.FuncAnimation(fig, draw, frames=n)
    path = Path(path)
    anim.save(clear_link(path), writer=animation.PillowWriter(fps=fps))
    plt.close(fig)
    return path
