"""``--csv FILE``: one row per epoch. A stable contract other tools read:

``t_s`` (vehicle time, seconds, as in the messages' own time fields),
``height_fused_m``, ``sigma_fused_m``, ``height_gnss_ch_m``,
``height_rng_ch_m``, ``height_baro_ch_m``, ``gnss_ok``, ``rng_ok``,
``baro_ok`` (1/0: the source is nominal or in caution), ``alarm`` (the
overall state as a word). Heights in metres above the reference; NaN as
``nan``. Times print with microsecond resolution, heights with 0.1 mm.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Optional

from ..report import EpochReport, RunSummary
from .base import Sink

COLUMNS = (
    "t_s",
    "height_fused_m",
    "sigma_fused_m",
    "height_gnss_ch_m",
    "height_rng_ch_m",
    "height_baro_ch_m",
    "gnss_ok",
    "rng_ok",
    "baro_ok",
    "alarm",
)


def _f(v: float) -> str:
    return "nan" if v != v else f"{v:.4f}"


def csv_row(r: EpochReport) -> list[str]:
    ch = r.channels
    return [
        f"{r.t_us * 1e-6:.6f}",
        _f(r.height_fused_m),
        _f(r.sigma_fused_m),
        _f(ch[0].height_ref_m),
        _f(ch[1].height_ref_m),
        _f(ch[2].height_ref_m),
        "1" if r.ok("gnss") else "0",
        "1" if r.ok("rangefinder") else "0",
        "1" if r.ok("baro_ins") else "0",
        r.overall,
    ]


class CsvSink(Sink):
    name = "csv"

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._fh: Optional[object] = None
        self._w = None

    def start(self, info: dict) -> None:
        self._fh = open(self.path, "w", newline="", encoding="utf-8")
        self._w = csv.writer(self._fh)
        self._w.writerow(COLUMNS)

    def epoch(self, report: EpochReport) -> None:
        self._w.writerow(csv_row(report))

    def close(self, summary: RunSummary) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
