"""Integrity scorecard metrics: pure functions over alarm events and height series.

Used by ``bench/integrity.py`` and unit-tested in ``tests/test_scorecard_metrics.py``.
Everything here is a pure function of its arguments (no I/O, no globals).

Conventions
-----------
* Times are *vehicle* time in seconds (``AlarmEvent.t_s``), one boot (the
  scorecard's logs do not reboot). Anything with ``t_s``, ``source``,
  ``state`` and ``previous`` attributes works as an alarm event
  (:class:`mavnav.report.AlarmEvent`, or the baseline's, which is the same type).
* An *alarm* is a transition into the state ``"alarm"`` from any other state
  (``caution`` and ``unavailable`` are not alarms: a stale source is
  unavailable, not faulty).
* A fault is *detected* when the first alarm of any source falls inside
  ``[onset_s, end_s + grace_s]``. Its *time-to-alarm* is that alarm's time
  minus ``onset_s``. It is *isolated* when every source alarming at that
  first instant is the fault's own source (an alarm of two sources at once,
  one of them right, is not an isolation).
* *False alarms* are alarm transitions outside every fault window
  (``[onset_s, end_s + margin_s]``), counted per hour of vehicle time.
* Height errors are evaluated on the truth grid: at each truth time the
  estimate is the latest one at or before it (sample and hold, what a
  consumer of the estimate would have had), NaN before the first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, List, Optional, Sequence, Tuple

import numpy as np

Window = Tuple[float, float]


# ---------------------------------------------------------------- alarms


def alarm_onsets(alarms: Iterable) -> list:
    """The events that enter the ``alarm`` state (from any other state), in order."""
    return [ev for ev in alarms if ev.state == "alarm" and ev.previous != "alarm"]


@dataclass(frozen=True)
class Detection:
    detected: bool
    tta_s: float  # time-to-alarm (NaN if not detected)
    isolated: bool  # the alarming sources at the first alarm are exactly {fault source}
    first_sources: Tuple[str, ...]  # sources alarming at the first alarm instant (sorted)


def detect(alarms: Sequence, onset_s: float, end_s: float, source: str, grace_s: float = 0.0) -> Detection:
    """Detection, time-to-alarm and isolation of one fault ``[onset_s, end_s]``.

    The first alarm transition with ``onset_s <= t_s <= end_s + grace_s``
    counts; every alarm transition at that same instant (within 1 us) forms
    the set of blamed sources.
    """
    hits = [ev for ev in alarm_onsets(alarms) if onset_s <= ev.t_s <= end_s + grace_s]
    if not hits:
        return Detection(False, math.nan, False, ())
    t_first = min(ev.t_s for ev in hits)
    blamed = tuple(sorted({ev.source for ev in hits if abs(ev.t_s - t_first) < 1e-6}))
    return Detection(True, t_first - onset_s, blamed == (source,), blamed)


def tta_stats(ttas: Iterable[float]) -> Tuple[float, float]:
    """(median, 95th percentile) of the finite times-to-alarm; NaN, NaN if none.

    Percentiles by linear interpolation between order statistics (numpy's
    default): with n values sorted ``x[0..n-1]`` the q-quantile is at
    position ``q (n - 1)``.
    """
    v = np.asarray([t for t in ttas if t == t and math.isfinite(t)], dtype=float)
    if v.size == 0:
        return math.nan, math.nan
    return float(np.median(v)), float(np.percentile(v, 95))


def isolation_rate(detections: Iterable[Detection]) -> Tuple[int, int]:
    """(correctly isolated, detected) over the detected faults."""
    det = [d for d in detections if d.detected]
    return sum(1 for d in det if d.isolated), len(det)


def false_alarms(alarms: Iterable, windows: Sequence[Window] = (), margin_s: float = 0.0) -> int:
    """Alarm transitions outside every window ``[a, b + margin_s]``."""
    n = 0
    for ev in alarm_onsets(alarms):
        if not any(a <= ev.t_s <= b + margin_s for a, b in windows):
            n += 1
    return n


def per_hour(count: int, duration_s: float) -> float:
    """Events per hour of vehicle time (NaN for no exposure)."""
    return count * 3600.0 / duration_s if duration_s > 0 else math.nan


def poisson_upper_95(count: int, duration_s: float) -> float:
    """One-sided 95 % upper bound of a Poisson rate per hour (0 events: 3.0 / hours).

    Exact (Garwood) bound: ``chi2.ppf(0.95, 2 (count + 1)) / 2`` events.
    """
    from scipy import stats

    if duration_s <= 0:
        return math.nan
    return float(stats.chi2.ppf(0.95, 2 * (count + 1)) / 2.0) * 3600.0 / duration_s


# ---------------------------------------------------------------- height errors


def hold_at(t_est: Sequence[float], v_est: Sequence[float], t_query: Sequence[float]) -> np.ndarray:
    """The latest estimate at or before each query time (NaN before the first)."""
    t_est = np.asarray(t_est, dtype=float)
    v_est = np.asarray(v_est, dtype=float)
    t_query = np.asarray(t_query, dtype=float)
    idx = np.searchsorted(t_est, t_query, side="right") - 1
    out = np.full(t_query.shape, np.nan)
    ok = idx >= 0
    out[ok] = v_est[idx[ok]]
    return out


def in_windows(t: Sequence[float], windows: Sequence[Window]) -> np.ndarray:
    """Boolean mask: ``t`` inside any closed window ``[a, b]``."""
    t = np.asarray(t, dtype=float)
    m = np.zeros(t.shape, dtype=bool)
    for a, b in windows:
        m |= (t >= a) & (t <= b)
    return m


def height_errors(t_est, h_est, t_truth, h_truth, windows: Optional[Sequence[Window]] = None,
                  inside: bool = True) -> Tuple[np.ndarray, int]:
    """Errors (estimate - truth) on the truth grid, restricted to ``windows``.

    ``windows`` None: every truth time. ``inside`` False: the truth times
    outside all windows. Returns (finite errors, number of truth times
    selected where the estimate was NaN, i.e. unavailable).
    """
    t_truth = np.asarray(t_truth, dtype=float)
    h_truth = np.asarray(h_truth, dtype=float)
    est = hold_at(t_est, h_est, t_truth)
    sel = np.ones(t_truth.shape, dtype=bool) if windows is None else in_windows(t_truth, windows)
    if not inside:
        sel = ~sel
    sel &= np.isfinite(h_truth)
    e = est[sel] - h_truth[sel]
    finite = np.isfinite(e)
    return e[finite], int((~finite).sum())


def rms(errors: Sequence[float]) -> float:
    e = np.asarray(errors, dtype=float)
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan


def pooled_rms(parts: Iterable[Tuple[float, int]]) -> float:
    """RMS of several runs pooled: ``parts`` = (sum of squared errors, count) each."""
    ss, n = 0.0, 0
    for s, k in parts:
        ss += s
        n += k
    return math.sqrt(ss / n) if n else math.nan


def icao_band(rms_m: float) -> str:
    """The best ICAO approach category whose vertical RMS upper bound the value meets
    (MODEL.md section 1: CAT III 0.3 m, CAT II 0.85 m, CAT I 2.0 m)."""
    if not (rms_m == rms_m):
        return "-"
    for name, limit in (("CAT III", 0.3), ("CAT II", 0.85), ("CAT I", 2.0)):
        if rms_m <= limit:
            return name
    return "none"


ICAO_BANDS: List[Tuple[str, float, float]] = [
    ("CAT I", 1.5, 2.0),
    ("CAT II", 0.7, 0.85),
    ("CAT III", 0.2, 0.3),
]
