"""``--csv FILE``: one row per epoch. A stable contract other tools read:

``t_s`` (vehicle time, seconds, as in the messages' own time fields),
``height_fused_m``, ``sigma_fused_m``, ``height_gnss_ch_m``,
``height_rng_ch_m``, ``height_baro_ch_m``, ``gnss_ok``, ``rng_ok``,
``baro_ok`` (1/0: the source is nominal or in caution), ``alarm`` (the
overall state as a word), ``boot`` (the vehicle boot the time belongs to:
0, then one more at every reboot), ``event`` (empty on an epoch's row).
Heights in metres above the reference; NaN as ``nan``. Times print with
microsecond resolution, heights with 0.1 mm.

*Event rows* (``event`` not empty) say what happened between epochs, as it
happens: ``reboot`` (at the new boot's first vehicle time), ``link lost``
(written and flushed when the receive clock passes the timeout, while the
link is down, at the vehicle time of the last epoch), ``link recovered``,
``clock step``, ``home moved`` (the autopilot's home moved: the heights of
the rows after it are above the new home). Their other columns are empty: a reader of epochs skips
rows whose ``event`` is set.

Rows reach the file as the run goes, not only at close: on a live link
(``info["live"]``) after every epoch, so a reader of the file is never behind
what the console shows; otherwise at least every ``flush_s`` (1 s) of receive
time (the samples' ``recv_s``), and whenever the link is lost.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Optional

from ..report import EpochReport, RunSummary
from ..home_frame import home_moved_text
from ..sensors import BARO_INS, GNSS, RANGEFINDER
from ..samples import LinkLost, LinkRecovered, Notice, Reboot, ReferenceMoved
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
    "boot",
    "event",
)
_EMPTY = [""] * (len(COLUMNS) - 3)  # the epoch columns of an event row


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
        "1" if r.ok(GNSS) else "0",
        "1" if r.ok(RANGEFINDER) else "0",
        "1" if r.ok(BARO_INS) else "0",
        r.overall,
        str(r.boot),
        "",
    ]


def event_row(t_us: Optional[int], boot: Optional[int], text: str) -> list[str]:
    """A row saying what happened: ``t_s`` and ``boot`` (empty if not known yet) and ``event``."""
    return [f"{t_us * 1e-6:.6f}" if t_us is not None else "", *_EMPTY, "" if boot is None else str(boot), text]


class CsvSink(Sink):
    name = "csv"

    def __init__(self, path: str | Path, flush_s: float = 1.0):
        self.path = Path(path)
        self.flush_s = flush_s
        self._fh: Optional[object] = None
        self._w = None
        self._live = False
        self._pending = 0  # rows written since the last flush
        self._recv_s: Optional[float] = None  # latest receive time seen
        self._flushed_recv_s: Optional[float] = None
        self._last: tuple = (None, None)  # (t_us, boot) of the latest epoch

    def start(self, info: dict) -> None:
        self._live = bool(info.get("live"))
        self._fh = open(self.path, "w", newline="", encoding="utf-8")
        self._w = csv.writer(self._fh)
        self._w.writerow(COLUMNS)
        self._fh.flush()

    def sample(self, s) -> None:
        recv = getattr(s, "recv_s", None)
        if recv is not None:
            self._recv_s = recv
            if self._flushed_recv_s is None:
                self._flushed_recv_s = recv
        ts = type(s)
        t_us, boot = self._last
        if ts is LinkLost:
            self._event(t_us, boot, f"link lost: no data from the vehicle for {s.silent_s:.1f} s")
            self._flush()  # said while it lasts, not when data returns
        elif ts is LinkRecovered:
            self._event(t_us, boot, f"link recovered after {s.outage_s:.1f} s")
        elif ts is Reboot:
            self._event(s.t_us, s.boot, f"reboot: vehicle time restarted at {s.t_us * 1e-6:.3f} s after "
                                        f"{s.last_t_us * 1e-6:.3f} s of boot {s.boot - 1}")
            self._last = (s.t_us, s.boot)
        elif ts is Notice and s.kind == "clock_step":
            self._event(t_us, boot, f"clock step: {s.text}")
        elif ts is ReferenceMoved:
            self._event(s.t_us, s.boot, f"home moved: {home_moved_text(s)}")

    def imu_run(self, run, i: int, j: int) -> None:
        """``sample`` of IMU samples ``i .. j - 1`` of an onboard log's run
        (see :mod:`.base`): their receive times, the vehicle times in s."""
        if self._flushed_recv_s is None:
            self._flushed_recv_s = run.t_us[i] * 1e-6
        self._recv_s = run.t_us[j - 1] * 1e-6

    def _event(self, t_us, boot, text: str) -> None:
        self._w.writerow(event_row(t_us, boot, text))
        self._pending += 1

    def epoch(self, report: EpochReport) -> None:
        self._last = (report.t_us, report.boot)
        self._w.writerow(csv_row(report))
        self._pending += 1
        if self._live or (self._recv_s is not None and abs(self._recv_s - self._flushed_recv_s) >= self.flush_s):
            self._flush()

    def _flush(self) -> None:
        self._fh.flush()
        self._pending = 0
        self._flushed_recv_s = self._recv_s

    def close(self, summary: RunSummary) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
