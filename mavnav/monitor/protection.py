"""The vertical protection level by solution separation: the fused height's
error bound under no fault and under a fault of each height source that the
channel comparison cannot see.

``k_ff * sigma_0`` bounds the fused height's error with every source healthy.
That is not enough: a channel re-initialised from another, or one whose
sensor has barely anchored it, disagrees with the rest by little whatever
the rest does, so the comparison cannot see a fault in them. For each source
whose channel is in the output, the subset solution without that channel
(the BLUE of the other used channels) differs from the full one by
``Delta_i``; the comparison sees a fault of source ``i`` once ``|Delta_i|``
passes ``k_fa * sd(Delta_i)``, so the largest undetected error of the full
solution is bounded by

    PL_i = k_fa * sd(Delta_i) + k_md * sigma_i

(``sigma_i`` the subset's own error sd, ``k_md`` its missed-detection
quantile; the ARAIM form). A source whose channel is the only one used has
no subset: nothing can see its fault, and its level is infinite. The
protection level is the largest of ``k_ff * sigma_0`` and every ``PL_i``.

Pure: the channels' height covariance in, the levels out.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence



def _subset_weights(cov: Sequence[Sequence[float]], drop: int) -> list[float]:
    """BLUE weights of every channel of ``cov`` but ``drop`` (zero there); at
    most two remain, so in closed form (one: itself; two: the 2x2 BLUE)."""
    n = len(cov)
    keep = [k for k in range(n) if k != drop]
    out = [0.0] * n
    if len(keep) == 1:
        out[keep[0]] = 1.0
        return out
    a, b = keep
    paa, pbb, pab = cov[a][a], cov[b][b], cov[a][b]
    den = paa + pbb - 2.0 * pab
    if not den > 0.0:  # the two are one: either will do
        out[a] = 1.0
        return out
    out[a] = (pbb - pab) / den
    out[b] = (paa - pab) / den
    return out


def _quad(w: Sequence[float], cov: Sequence[Sequence[float]]) -> float:
    n = len(w)
    return max(sum(w[a] * w[b] * cov[a][b] for a in range(n) for b in range(n)), 0.0)


def separation_levels(cov: Sequence[Sequence[float]], weights: Sequence[float], k_fa: float,
                      k_md: float, lean: int = -1, own_var: Optional[Sequence[float]] = None) -> list[float]:
    """``PL_i`` for the fault of each channel of the output, in order: ``cov``
    is the height error covariance of the channels in the output (at most
    three) and ``weights`` their weights in the fused height.

    ``lean``: the channel of a source the others lean on (the baro, whose
    changes the aux channels take), -1 none; ``own_var``: each channel's own
    sensor's noise variance. A fault of the leaned-on source moves the
    channels that lean on it too, so the subset without it is no better than
    its own sensors: its sigma takes ``sum(w_k^2 own_var_k)`` over the
    channels left (a GNSS reporting 10 m cannot vouch for the baro at 4 m,
    however well the baro's own rows pin its channel)."""
    n = len(weights)
    if n == 1:
        return [math.inf]
    out = []
    for c in range(n):
        wi = _subset_weights(cov, c)
        sd_delta = math.sqrt(_quad([a - b for a, b in zip(weights, wi)], cov))
        var_i = _quad(wi, cov)
        if c == lean and own_var is not None:
            var_i += sum(w * w * v for w, v in zip(wi, own_var))
        out.append(k_fa * sd_delta + k_md * math.sqrt(var_i))
    return out


def protection_level(sigma_fused_m: float, cov: Sequence[Sequence[float]], weights: Sequence[float],
                     k_ff: float, k_fa: float, k_md: float, lean: int = -1,
                     own_var: Optional[Sequence[float]] = None) -> tuple[float, int]:
    """The vertical protection level, and the index (into ``cov``) of the
    channel whose fault hypothesis sets it (-1: the fault-free bound
    ``k_ff * sigma_fused_m``). No channel in the output: infinite."""
    if sigma_fused_m != sigma_fused_m or not weights:
        return math.inf, -1
    vpl, limit = k_ff * sigma_fused_m, -1
    for c, pl in enumerate(separation_levels(cov, weights, k_fa, k_md, lean, own_var)):
        if not pl <= vpl:
            vpl, limit = pl, c
    return vpl, limit
