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
        # name, diff_m, threshold_m, exceeded, valid (positionally: once per pair per epoch)
        out.append(PairReport(PAIR_NAMES[p], diff, thr, valid and abs(diff) > thr, valid))
    return tuple(out)


_MIN_DIFF_VAR = 1e-12  # m^2: the pair difference's variance floor


def _diff_sigma_list(bank: ChannelBank, floor_var) -> list[float]:
    ph = bank.P[:, 0, 0].tolist()  # Python floats: the same arithmetic without numpy scalars
    pc = bank.Pc[:, 0, 0].tolist()
    # max(ph[c], floor_var[c]) once per channel (max(a, b) is a unless b > a: so NaN stays as max keeps it)
    m = [f if f > v else v for v, f in zip(ph, floor_var)]
    out = []
    for p, (a, b) in enumerate(PAIRS):
        v = m[a] + m[b] - 2.0 * pc[p]
        out.append(math.sqrt(_MIN_DIFF_VAR if _MIN_DIFF_VAR > v else v))  # max(v, 1e-12)
    return out


def diff_sigmas(bank: ChannelBank, floor_var=(0.0, 0.0, 0.0)) -> np.ndarray:
    """sqrt(P_a + P_b - 2 P_ab) of the heights, for every pair; each channel's
    ``P_HH`` raised to at least ``floor_var[c]`` (its sensor's own variance)."""
    return np.array(_diff_sigma_list(bank, floor_var))


def pair_reports_scaled(bank: ChannelBank, available, floor_var, k: float) -> tuple[PairReport, ...]:
    """``pair_reports(bank, available, k * diff_sigmas(bank, floor_var))``,
    per epoch, without the array between them (``tests/test_monitor_decision.py``)."""
    return pair_reports(bank, available, [k * s for s in _diff_sigma_list(bank, floor_var)])


__all__ = ["Decision", "pair_reports", "pair_reports_scaled", "diff_sigmas", "GNSS", "RNG", "BARO", "PAIRS"]
