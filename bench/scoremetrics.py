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
from typing import Iterable, Optional, Sequence, Tuple

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


# ---------------------------------------------------------------- one run of a family

# Sources that are not sensors: their alarms are false alarms, never wrong exclusions.
NON_SENSOR_SOURCES = ("input",)
# A fault's source as the monitor may name it: the current monitor has baro_ins, a rewrite
# may split baro and ins. Faults name one of these groups.
SOURCE_GROUPS = {
    "gnss": ("gnss",),
    "rangefinder": ("rangefinder",),
    "baro": ("baro_ins", "baro"),
    "ins": ("baro_ins", "ins"),
}
USABLE_STATES = ("nominal", "caution")  # the output is offered as usable


@dataclass(frozen=True)
class RunScore:
    """What one run of one contender scored (see :func:`score_run`)."""

    fault: bool  # a fault run (False: a nominal run, no alarm expected)
    detected: bool  # an alarm of any source inside the fault window (False on nominal runs)
    tta_s: float  # first alarm in the window minus onset (NaN if none)
    isolated: bool  # every source alarming at that first instant is the fault's
    blamed: Tuple[str, ...]  # sources alarming at the first instant in the window
    wrong_exclusions: Tuple[str, ...]  # healthy sensor sources that entered alarm (from the onset on)
    false_alarms: int  # alarm transitions not explained by the fault (see score_run)
    hazardous_s: float  # time the output was > hazard_m from truth while offered as usable
    max_usable_error_m: float  # largest |error| of an output offered as usable
    available_frac: float  # share of the run's time with a usable output
    alarmed: Tuple[str, ...]  # every source that entered alarm at any time
    caution_frac: float = math.nan  # share of the run's time in overall caution (NaN: no states)

    @property
    def hazardous(self) -> bool:
        return self.hazardous_s > 0.0

    @property
    def right(self) -> bool:
        """Everything right: the fault detected and isolated (fault runs), no wrong
        exclusion, no false alarm, no hazardous output."""
        ok = not self.wrong_exclusions and self.false_alarms == 0 and not self.hazardous
        return ok and (self.detected and self.isolated if self.fault else True)


def score_run(alarms: Sequence, t_est: Sequence[float], h_est: Sequence[float], overall: Optional[Sequence[str]],
              t_truth: Sequence[float], h_truth: Sequence[float], *, window: Optional[Window] = None,
              expected: Sequence[str] = (), allowed: Sequence[str] = (), hazard_m: float = 3.0,
              max_hold_s: float = 0.5) -> RunScore:
    """Score one run from the monitor's public outputs only.

    ``alarms``: state-change events (``t_s``, ``source``, ``state``,
    ``previous``); ``t_est``/``h_est``/``overall``: per output epoch the
    vehicle time, the fused height and the overall state (``overall`` None:
    a contender with no state, whose every output counts as usable).

    * ``window`` ``(onset_s, end_s)`` with ``expected`` (the fault's source
      names): a fault run. *Detected*: an alarm transition of any source in
      ``[onset_s, end_s]``; *time-to-alarm* and *isolation* from the first
      (isolated: every source alarming at that instant is in ``expected``).
      *False alarms*: alarm transitions before the onset.
    * no ``expected``: a nominal run (``window``, if given, is only
      reported); *false alarms*: every alarm transition of a source not in
      ``allowed``.
    * *Wrong exclusions*: sensor sources (not ``input``) outside ``expected``
      and ``allowed`` that enter alarm at or after the onset (fault runs) or
      at any time (nominal runs).
    * *Hazardous*: time at output epochs where the output is offered as
      usable (overall nominal or caution, finite height) and is more than
      ``hazard_m`` from the truth (linear interpolation of the truth, only
      inside its time span); each epoch counts until the next, at most
      ``max_hold_s``. *Available*: the share of that time with a usable
      output; *caution*: the share with the overall state in caution (on a
      nominal run, the time a healthy flight is shown as doubtful).
    """
    onsets = alarm_onsets(alarms)
    exp, allow = set(expected), set(allowed)
    fault = bool(exp)
    alarmed = tuple(sorted({ev.source for ev in onsets}))
    detected, tta, isolated, blamed = False, math.nan, False, ()
    t_from = -math.inf
    if fault:
        if window is None:
            raise ValueError("a fault run needs its window")
        on, end = window
        t_from = on
        hits = [ev for ev in onsets if on <= ev.t_s <= end]
        if hits:
            t_first = min(ev.t_s for ev in hits)
            blamed = tuple(sorted({ev.source for ev in hits if abs(ev.t_s - t_first) < 1e-6}))
            detected, tta, isolated = True, t_first - on, set(blamed) <= exp
        fa = sum(1 for ev in onsets if ev.t_s < on)
    else:
        fa = sum(1 for ev in onsets if ev.source not in allow)
    healthy_skip = exp | allow | set(NON_SENSOR_SOURCES)
    wrong = tuple(sorted({ev.source for ev in onsets if ev.t_s >= t_from and ev.source not in healthy_skip}))

    t = np.asarray(t_est, dtype=float)
    h = np.asarray(h_est, dtype=float)
    haz_s, avail_s, span_s, max_err, caution_s = 0.0, 0.0, 0.0, 0.0, math.nan
    if t.size:
        dt = np.minimum(np.diff(t, append=t[-1]), max_hold_s)
        dt = np.maximum(dt, 0.0)
        tt, ht = np.asarray(t_truth, dtype=float), np.asarray(h_truth, dtype=float)
        truth = np.interp(t, tt, ht) if tt.size else np.full(t.shape, np.nan)
        inside = (t >= tt[0]) & (t <= tt[-1]) if tt.size else np.zeros(t.shape, bool)
        usable = np.isfinite(h)
        if overall is not None:
            states = np.asarray(overall, dtype=object)
            usable &= np.isin(states, USABLE_STATES)
            caution_s = float(dt[states == "caution"].sum())
        err = np.abs(h - truth)
        bad = usable & inside & (err > hazard_m)
        haz_s = float(dt[bad].sum())
        avail_s = float(dt[usable].sum())
        span_s = float(dt.sum())
        sel = usable & inside & np.isfinite(err)
        max_err = float(err[sel].max()) if sel.any() else math.nan
    return RunScore(fault=fault, detected=detected, tta_s=tta, isolated=isolated, blamed=blamed,
                    wrong_exclusions=wrong, false_alarms=fa, hazardous_s=haz_s, max_usable_error_m=max_err,
                    available_frac=avail_s / span_s if span_s > 0 else math.nan, alarmed=alarmed,
                    caution_frac=caution_s / span_s if span_s > 0 else math.nan)


def misleading(t_est: Sequence[float], h_est: Sequence[float], pl_m: Sequence[float], overall: Sequence[str],
               t_truth: Sequence[float], h_truth: Sequence[float], max_hold_s: float = 0.5) -> Tuple[float, float]:
    """Does the protection level bound the error? ``(misleading_s, usable_s)``:
    the time the output was offered as usable (nominal or caution, finite
    height and level) with its error beyond its own protection level, and the
    usable time it is out of (truth interpolated, only inside its span; each
    epoch counts until the next, at most ``max_hold_s``)."""
    t = np.asarray(t_est, dtype=float)
    if t.size == 0 or len(t_truth) == 0:
        return 0.0, 0.0
    h, pl = np.asarray(h_est, dtype=float), np.asarray(pl_m, dtype=float)
    tt, ht = np.asarray(t_truth, dtype=float), np.asarray(h_truth, dtype=float)
    dt = np.maximum(np.minimum(np.diff(t, append=t[-1]), max_hold_s), 0.0)
    usable = (np.isfinite(h) & np.isfinite(pl) & (t >= tt[0]) & (t <= tt[-1])
              & np.isin(np.asarray(overall, dtype=object), USABLE_STATES))
    err = np.abs(h - np.interp(t, tt, ht))
    return float(dt[usable & (err > pl)].sum()), float(dt[usable].sum())


# ---------------------------------------------------------------- the output against every sensor

STATES = ("nominal", "caution", "unavailable", "alarm")


def departure(t_s, fused_m, others_m, states, margin_m: float) -> tuple[dict, float, float]:
    """Seconds (each epoch holds until the next) with ``fused_m`` finite and more
    than ``margin_m`` from every finite row of ``others_m``, by state; the
    largest such distance and its time. An epoch with no other height is not
    counted."""
    t_s = np.asarray(t_s, float)
    f = np.asarray(fused_m, float)
    o = np.asarray(others_m, float).reshape(-1, t_s.size)
    with np.errstate(invalid="ignore"):
        gap = np.abs(o - f)
        gap[~np.isfinite(gap)] = np.inf
        d = gap.min(axis=0)
    ok = np.isfinite(f) & np.isfinite(d)
    dt = np.diff(t_s, append=t_s[-1]) if t_s.size else t_s
    far = ok & (d > margin_m)
    st = np.asarray(states)
    out = {s: float(dt[far & (st == s)].sum()) for s in STATES}
    if not ok.any():
        return out, math.nan, math.nan
    k = int(np.argmax(np.where(ok, d, -np.inf)))
    return out, float(d[k]), float(t_s[k])
