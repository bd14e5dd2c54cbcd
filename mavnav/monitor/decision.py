"""What a decision logic returns for one epoch, and the pieces both logics share."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..bank import BARO, GNSS, PAIRS, RNG, ChannelBank
from ..report import PAIR_NAMES, PairReport


@dataclass
class Decision:
    available: tuple  # per channel: usable for comparison
    used: tuple  # per channel: in the fused output
    pairs: tuple  # PairReport in PAIR_NAMES order
    sources: dict  # "gnss" | "rangefinder" | "baro_ins" -> SourceStatus
    height_fused_m: float
    sigma_fused_m: float
    events: list = field(default_factory=list)


def pair_reports(bank: ChannelBank, available, thresholds) -> tuple[PairReport, ...]:
    """Differences ``H_a - H_b`` of the channel pairs against their thresholds."""
    out = []
    for p, (a, b) in enumerate(PAIRS):
        diff = float(bank.x[a, 0] - bank.x[b, 0])
        thr = float(thresholds[p])
        valid = bool(available[a] and available[b])
        out.append(PairReport(name=PAIR_NAMES[p], diff_m=diff, threshold_m=thr,
                              exceeded=valid and abs(diff) > thr, valid=valid))
    return tuple(out)


def diff_sigmas(bank: ChannelBank, floor_var=(0.0, 0.0, 0.0)) -> np.ndarray:
    """sqrt(P_a + P_b - 2 P_ab) of the heights, for every pair; each channel's
    ``P_HH`` raised to at least ``floor_var[c]`` (its sensor's own variance)."""
    out = np.empty(len(PAIRS))
    P, Pc = bank.P, bank.Pc
    for p, (a, b) in enumerate(PAIRS):
        pa, pb = P[a, 0, 0], P[b, 0, 0]
        v = max(pa, floor_var[a]) + max(pb, floor_var[b]) - 2.0 * Pc[p, 0, 0]
        out[p] = math.sqrt(max(v, 1e-12))
    return out


__all__ = ["Decision", "pair_reports", "diff_sigmas", "GNSS", "RNG", "BARO", "PAIRS"]
