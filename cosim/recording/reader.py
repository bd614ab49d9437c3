"""Read a recording back (tests, checks): sample counts, one entity's values, the layout.

rerun 0.41 has no dataframe reader in the SDK proper: ``rerun.dataframe`` was removed in 0.29
and ``rerun.recording`` in 0.34, and the catalog query API (``rerun.server.Server`` +
``CatalogClient``) needs the ``datafusion`` extra and a local server. Its public reader is
``rerun.chunk.RrdReader`` (chunks as Arrow record batches); these few functions sit on it.

Owns: reading a recording back with rerun's public reader. Boundaries: read only.
"""
from __future__ import annotations

import re

import numpy as np

from .layout import SIM_TIME


def _chunks(path, blueprint: bool = False):
    """The chunks of the recording (or of its last blueprint) in an .rrd file; a file without
    footer (an interrupted writer) streams too."""
    from rerun.chunk import RrdReader
    reader = RrdReader(str(path))
    if not blueprint:
        return reader.stream()
    stores = reader.blueprints()
    return reader.stream(store=stores[-1]) if stores else []


def read_back(path) -> dict:
    """{entity_path: number of samples}: rows on the timelines, or 1 for an entity with only
    static data (text, drawing settings). Rerun's own entities (``/__properties``) are left out;
    static series names of a time-series entity do not add to its count."""
    counts, static = {}, set()
    for chunk in _chunks(path):
        entity = chunk.entity_path
        if entity.startswith("/__"):
            continue
        if chunk.is_static:
            static.add(entity)
        else:
            counts[entity] = counts.get(entity, 0) + chunk.num_rows
    for entity in static:
        counts.setdefault(entity, 1)
    return dict(sorted(counts.items()))


def chunk_counts(path) -> dict:
    """{entity_path: number of chunks with samples on the timelines} (``rerun rrd stats`` warns
    when these are many times the entity count)."""
    counts = {}
    for chunk in _chunks(path):
        if not chunk.is_static and not chunk.entity_path.startswith("/__"):
            counts[chunk.entity_path] = counts.get(chunk.entity_path, 0) + 1
    return counts


def read_scalars(path, entity: str, timeline: str = SIM_TIME):
    """(index, values) of a scalar entity: ``index`` in seconds for ``sim_time`` (integers for
    the sequence timelines), ``values`` (n, m) as logged, sorted by the index."""
    idx, vals = [], []
    for chunk in _chunks(path):
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if timeline not in batch.schema.names:
            continue
        i = batch.column(timeline).cast("int64").to_numpy(zero_copy_only=False)
        idx.append(i / 1e9 if timeline == SIM_TIME else i)
        vals += [np.asarray(v, dtype=float) for v in batch.column("Scalars:scalars").to_pylist()]
    if not idx:
        raise KeyError(f"{path}: no scalar samples of {entity} on timeline {timeline}")
    index, values = np.concatenate(idx), np.array(vals)
    order = np.argsort(index, kind="stable")
    return index[order], values[order]


def read_column(path, entity: str, column: str, timeline: str = SIM_TIME) -> list:
    """[(index, value)] of any component column of an entity (e.g. ``LineStrips2D:strips``),
    sorted by the index (``sim_time`` in ns)."""
    rows = []
    for chunk in _chunks(path):
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if timeline in batch.schema.names and column in batch.schema.names:
            rows += zip(batch.column(timeline).cast("int64").to_pylist(), batch.column(column).to_pylist())
    return sorted(rows, key=lambda r: r[0])


def read_static(path, entity: str, column: str):
    """The last static value of a component column (e.g. ``SeriesLines:names``), or None."""
    value = None
    for chunk in _chunks(path):
        if chunk.entity_path == entity and chunk.is_static:
            batch = chunk.to_record_batch()
            if column in batch.schema.names and batch.num_rows:
                value = batch.column(column).to_pylist()[-1]
    return value


def read_blueprint(path) -> list:
    """The views of the last blueprint in an .rrd: [{"name", "class", "origin", "contents"}]
    (an empty list if the file has no blueprint)."""
    views = {}
    for chunk in _chunks(path, blueprint=True):
        m = re.match(r"^/view/([^/]+)(/ViewContents)?$", chunk.entity_path)
        if not m:
            continue
        view = views.setdefault(m.group(1), {"name": None, "class": None, "origin": None, "contents": []})
        batch = chunk.to_record_batch()
        row = {name: batch.column(name).to_pylist()[-1] for name in batch.schema.names
               if ":" in name and batch.num_rows}
        if m.group(2):
            view["contents"] = list(row.get("ViewContents:query") or [])
        else:
            view["name"] = _first(row.get("ViewBlueprint:display_name"))
            view["class"] = _first(row.get("ViewBlueprint:class_identifier"))
            view["origin"] = _first(row.get("ViewBlueprint:space_origin"))
    return list(views.values())


def _first(v):
    return v[0] if isinstance(v, list) and v else v
