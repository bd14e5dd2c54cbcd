"""What a decision logic returns for one epoch, and the pieces both logics share."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..bank import BARO, GNSS, PAIRS, RNG, ChannelBank
from ..report import PAIR_NAMES, PairReport


@dataclass(slots=True)
class Decision:
    available: tuple  # per channel: usable for comparison
    used: tuple  # per channel: in the fused output
    pairs: tuple  # PairReport in PAIR_NAMES order
    sources: dict  # sensors.SENSOR_SOURCES (gnss, rangefinder, baro_ins) -> SourceStatus (fresh each epoch:
    # the core adds the input's status to it and hands it to the report)
    height_fused_m: float
    sigma_fused_m: float
    events: list = field(default_factory=list)
    # the vertical protection level when the logic bounds the faults it cannot
    # see (NaN: the fault-free bound from sigma_fused_m, the paper's)
    vpl_m: float = math.nan


def pair_reports(bank: ChannelBank, available, thresholds) -> tuple[PairReport, ...]:
    """Differences ``H_a - H_b`` of the channel pairs against their thresholds."""
    out = []
    h = bank.x[:, 0].tolist()  # Python floats, as float() of each element
    thresholds = thresholds.tolist() if isinstance(thresholds, np.ndarray) else thresholds
    for p, (a, b) in enumerate(PAIRS):
        diff = h[a] - h[b]
        thr = float(thresholds[p])
        valid = bool(available[a] and available[b])
        out.append(PairReport(name=PAIR_NAMES[p], diff_m=diff, threshold_m=thr,
                              exceeded=valid and abs(diff) > thr, valid=valid))
    return tuple(out)


def diff_sigmas(bank: ChannelBank, floor_var=(0.0, 0.0, 0.0)) -> np.ndarray:
    """sqrt(P_a + P_b - 2 P_ab) of the heights, for every pair; each channel's
    ``P_HH`` raised to at least ``floor_var[c]`` (its sensor's own variance)."""
    out = np.empty(len(PAIRS))
    ph = bank.P[:, 0, 0].tolist()  # Python floats: the same arithmetic without numpy scalars
    pc = bank.Pc[:, 0, 0].tolist()
    for p, (a, b) in enumerate(PAIRS):
        pa, pb = ph[a], ph[b]
        v = max(pa, floor_var[a]) + max(pb, floor_var[b]) - 2.0 * pc[p]
        out[p] = math.sqrt(max(v, 1e-12))
    return out


def pair_reports_scaled(bank: ChannelBank, available, floor_var, k: float) -> tuple[PairReport, ...]:
    """``pair_reports(bank, available, k * diff_sigmas(bank, floor_var))`` on
    Python floats, per epoch: the same products, sums and square roots in the
    same order, without the arrays between them (``tests/test_monitor_decision.py``)."""
    ph = bank.P[:, 0, 0].tolist()
    pc = bank.Pc[:, 0, 0].tolist()
    h = bank.x[:, 0].tolist()
    out = []
    for p, (a, b) in enumerate(PAIRS):
        pa, pb = ph[a], ph[b]
        fa, fb = floor_var[a], floor_var[b]
        v = (fa if fa > pa else pa) + (fb if fb > pb else pb) - 2.0 * pc[p]  # max(), as max() picks (NaN too)
        thr = k * math.sqrt(1e-12 if 1e-12 > v else v)
        diff = h[a] - h[b]
        valid = bool(available[a] and available[b])
        out.append(PairReport(PAIR_NAMES[p], diff, thr, valid and abs(diff) > thr, valid))
    return tuple(out)


__all__ = ["Decision", "pair_reports", "pair_reports_scaled", "diff_sigmas", "GNSS", "RNG", "BARO", "PAIRS"]
