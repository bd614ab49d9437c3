"""The linkage drawing from the engines' node positions: pure numpy, no kinematics.

Each link is drawn twice:

* *straight*: a line between the link's end nodes (its joints, where the engine computed them);
* *deformed*: every node at its point on that line plus ``factor`` times its offset from it,
  ``drawn = chord(s) + factor * (node - chord(s))``, with ``chord(s)`` the point of the line at
  the node's station ``s`` along the link.

The offset from the line is the link's own elastic deformation (bending, and stretch between
the joints). Exaggerating it keeps the joints where they are, so a drawing never comes apart or
loops, whatever the factor; the joints' own elastic displacement is drawn at true scale (it is
a small fraction of a link length). Links are straight beams between their joints in every
bench mechanism, so the line is also the link's undeformed shape.

The factor is chosen from the largest offset seen (:func:`auto_factor`): a 1-2-5 number that
draws it at about 5 % of the longest link.

Owns: the linkage drawing from the engines' nodes and its exaggeration factor. Boundaries: no
kinematics.
"""
from __future__ import annotations

import numpy as np

from .layout import nice_factor

DRAWN_SHARE = 0.05          # the largest offset is drawn at about this share of the longest link


def fractions(stations, n: int) -> np.ndarray:
    """Position of each of ``n`` nodes along the link, 0 at the first node and 1 at the last:
    from the engine's stations when they fit, else evenly spaced."""
    s = None if stations is None else np.asarray(stations, dtype=float).ravel()
    if s is None or len(s) != n or n < 2 or s[-1] == s[0]:
        return np.linspace(0.0, 1.0, n)
    return (s - s[0]) / (s[-1] - s[0])


def chord(nodes, frac) -> np.ndarray:
    """Points of the line through the first and last node at the fractions ``frac``
    (``nodes``: (..., n, 2))."""
    nodes = np.asarray(nodes, dtype=float)
    p0, p1 = nodes[..., :1, :], nodes[..., -1:, :]
    return p0 + np.asarray(frac, dtype=float)[:, None] * (p1 - p0)


def largest_offset(nodes_by_link: dict, stations_by_link: dict | None = None) -> float:
    """Largest distance of a node from its link's line over the links (and frames) given [m]."""
    out = 0.0
    for link, nodes in nodes_by_link.items():
        nodes = np.asarray(nodes, dtype=float)
        if nodes.shape[-2] < 3:
            continue
        frac = fractions((stations_by_link or {}).get(link), nodes.shape[-2])
        d = np.linalg.norm(nodes - chord(nodes, frac), axis=-1)
        if d.size and np.isfinite(d).any():
            out = max(out, float(np.nanmax(d)))
    return out


def auto_factor(largest_offset_m: float, longest_link_m: float, share: float = DRAWN_SHARE) -> float:
    """The exaggeration that draws ``largest_offset_m`` at about ``share`` of the longest link
    (a 1-2-5 number, never below 1: a large deformation is drawn as it is)."""
    if not (largest_offset_m > 0 and longest_link_m > 0):
        return 1.0
    return nice_factor(share * longest_link_m / largest_offset_m)


def frame(nodes_by_link: dict, stations_by_link: dict | None, factor: float) -> tuple:
    """(straight strips, deformed strips, link names) of one frame: per link a 2-point line
    between its end nodes, and its nodes with the offsets from that line times ``factor``."""
    straight, deformed, names = [], [], []
    for link, nodes in nodes_by_link.items():
        nodes = np.asarray(nodes, dtype=float)
        if nodes.ndim != 2 or len(nodes) < 2 or not np.isfinite(nodes).all():
            continue
        frac = fractions((stations_by_link or {}).get(link), len(nodes))
        line = chord(nodes, frac)
        straight.append(nodes[[0, -1]])
        deformed.append(line + factor * (nodes - line))
        names.append(link)
    return straight, deformed, names


def block_strips(stacked: dict, n_frames: int, stations_by_link: dict | None, factor: float) -> tuple:
    """:func:`frame` of ``n_frames`` frames stacked per link (``{link: (F, n, 2)}``, e.g. a
    :class:`cosim.recording.batch.FrameBlock`'s nodes): ``(straight strips, deformed strips,
    strips per frame)``. The arithmetic is batched over the frames of each link (one frame at a
    time cost ~0.25 ms a frame, more than a transfer-matrix step); a link with a non-finite node
    is left out of that frame."""
    drawn = []
    for link, nodes in stacked.items():
        nodes = np.asarray(nodes, dtype=float)
        if nodes.ndim != 3 or nodes.shape[-1] != 2 or nodes.shape[1] < 2:
            continue
        frac = fractions((stations_by_link or {}).get(link), nodes.shape[1])
        line = chord(nodes, frac)
        drawn.append((nodes[:, [0, -1]], line + factor * (nodes - line), np.isfinite(nodes).all(axis=(1, 2))))
    straight, deformed, counts = [], [], []
    for i in range(n_frames):
        count = 0
        for ends, shape, finite in drawn:
            if finite[i]:
                straight.append(ends[i])
                deformed.append(shape[i])
                count += 1
        counts.append(count)
    return straight, deformed, counts
