"""Rerun recordings read back with rerun's own reader (:func:`read_rrd`), and a sink that
captures what the pipeline hands its sinks (:class:`Capture`).
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field

import pyarrow as pa
from rerun.chunk import RrdReader

from mavnav.sinks.base import Sink


@dataclass
class Recording:
    scalars: dict = field(default_factory=lambda: defaultdict(list))  # entity -> [(t_ns, values)]
    texts: dict = field(default_factory=lambda: defaultdict(list))  # entity -> [(t_ns, text, level)]
    states: dict = field(default_factory=lambda: defaultdict(list))  # entity -> [(t_ns, state)]
    docs: dict = field(default_factory=lambda: defaultdict(list))  # entity -> [(t_ns, text, media type)]
    static: dict = field(default_factory=lambda: defaultdict(set))  # entity -> component names
    timelines: set = field(default_factory=set)

    def sorted(self) -> "Recording":
        for table in (self.scalars, self.texts, self.states, self.docs):
            for rows in table.values():
                rows.sort(key=lambda r: r[0])
        return self

    @property
    def data_entities(self) -> set:
        return set(self.scalars) | set(self.texts) | set(self.states) | set(self.docs)


def read_rrd(path) -> Recording:
    out = Recording()
    for chunk in RrdReader(str(path)).stream():
        entity = chunk.entity_path.lstrip("/")
        if entity.startswith("__"):
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if chunk.is_static:
            out.static[entity].update(n for n in names if not n.startswith("rerun."))
            continue
        out.timelines.update(chunk.timeline_names)
        times = batch.column("vehicle_time").cast(pa.int64()).to_pylist()
        if "Scalars:scalars" in names:
            for t, v in zip(times, batch.column("Scalars:scalars").to_pylist()):
                out.scalars[entity].append((t, tuple(v)))
        if "TextLog:text" in names:
            texts = batch.column("TextLog:text").to_pylist()
            levels = batch.column("TextLog:level").to_pylist()
            for t, x, lv in zip(times, texts, levels):
                out.texts[entity].append((t, x[0], lv[0]))
        if "StateChange:state" in names:
            for t, s in zip(times, batch.column("StateChange:state").to_pylist()):
                out.states[entity].append((t, s[0]))
        if "TextDocument:text" in names:
            kinds = batch.column("TextDocument:media_type").to_pylist()
            for t, x, m in zip(times, batch.column("TextDocument:text").to_pylist(), kinds):
                out.docs[entity].append((t, x[0], m[0]))
    return out.sorted()


def same(a, b) -> bool:
    """Row lists equal, NaN equal to NaN."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b):
        if ra[0] != rb[0] or len(ra[1]) != len(rb[1]):
            return False
        for x, y in zip(ra[1], rb[1]):
            if not (x == y or (math.isnan(x) and math.isnan(y))):
                return False
    return True


class Capture(Sink):
    name = "capture"

    def __init__(self):
        self.samples, self.epochs, self.alarms, self.order = [], [], [], []

    def sample(self, s):
        self.samples.append(s)
        self.order.append(s)

    def epoch(self, r):
        self.epochs.append(r)
        self.order.append(r)

    def alarm(self, e):
        self.alarms.append(e)
