"""The INS's vertical acceleration error on real flights, measured against the
GNSS receiver's Doppler vertical velocity.

    python bench/ins_stats.py [--workers 2] [--min-imu-hz 20] [paths...]

For each flight whose GNSS logs a Doppler vertical velocity (ArduPilot GPS.VZ,
PX4 vel_d_m_s) and whose IMU runs at ``--min-imu-hz`` or more, the audit's own
pipeline builds the INS velocity increments (``dv_mps`` of every epoch: the
specific force along the vertical from the IMU and the attitude, less g, held
and integrated as the filters take it). At every GNSS sample with ``W``
seconds of continuous data behind it:

    e(W) = [V_ins(t) - V_ins(t - W)] - [v_dop(t) - v_dop(t - W)]

that is the integral of the INS's acceleration error over ``W`` plus twice the
Doppler's own noise. Printed per flight and window: the robust standard
deviation (1.4826 x the median absolute deviation about the median: a few
manoeuvres the Doppler lags do not set it) of ``e(W)``.

The model (``sensors.ins``: a first-order Gauss-Markov acceleration error of
RMS ``sigma_a`` and inverse correlation time ``alpha_a``) predicts

    Var e(W) = 2 sigma_a^2 / alpha_a^2 (alpha_a W - 1 + exp(-alpha_a W)) + 2 sigma_d^2

The last table fits ``sigma_a`` and ``sigma_d`` per flight at the configured
``alpha_a`` (least squares on the variances over the windows), and prints the
model's own prediction beside the measurement. These are the numbers that
size ``sensors.ins.sigma_a_mps2`` (docs/error_models.md).
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Optional

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from preamble import announce  # noqa: E402
from realflights import find_flights  # noqa: E402

from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.monitor import hypotheses  # noqa: E402
from mavnav.pipeline import run  # noqa: E402
from mavnav.samples import GnssHeight, SpecificForceUp  # noqa: E402

WINDOWS_S = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)
MAX_GAP_S = 1.5


def gm_var(sigma: float, alpha: float, w: float) -> float:
    """The variance of the integral over ``w`` of a Gauss-Markov process (RMS ``sigma``, rate ``alpha``)."""
    aw = alpha * w
    return 2.0 * sigma * sigma / (alpha * alpha) * (aw - 1.0 + math.exp(-aw))


def robust_sd(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x)))) if x.size else math.nan


class _Spy:
    """The epochs' INS increments, read where the monitor reads them."""

    def __init__(self):
        self.rows: list = []
        self._orig = hypotheses.HypothesisLogic._advance

    def __enter__(self):
        rows, orig = self.rows, self._orig

        def advance(logic, ep, t):
            rows.append((t * 1e-6, ep.dv_mps))
            return orig(logic, ep, t)

        hypotheses.HypothesisLogic._advance = advance
        return self

    def __exit__(self, *exc):
        hypotheses.HypothesisLogic._advance = self._orig


def flight(path: str, min_imu_hz: float) -> Optional[dict]:
    cfg = config_from_dict({})
    try:
        samples = list(open_log(path, cfg.ingest))
    except MavnavError:
        return None
    g = [(s.t_us * 1e-6, s.vel_up_mps) for s in samples
         if isinstance(s, GnssHeight) and getattr(s, "boot", 0) == 0
         and s.vel_up_mps is not None and math.isfinite(s.vel_up_mps)]
    if len(g) < 50:
        return None
    ti = [s.t_us for s in samples if isinstance(s, SpecificForceUp) and getattr(s, "boot", 0) == 0]
    imu_hz = len(ti) / max((ti[-1] - ti[0]) * 1e-6, 1e-9) if len(ti) > 1 else 0.0
    if imu_hz < min_imu_hz:
        return None
    with _Spy() as spy:
        run(samples, cfg, [])
    ep = np.asarray(spy.rows, dtype=float)
    back = np.nonzero(np.diff(ep[:, 0]) <= 0)[0] if ep.shape[0] > 1 else np.zeros(0, dtype=int)
    if back.size:
        ep = ep[:back[0] + 1]  # the first boot's epochs, as the GNSS samples above
    if ep.shape[0] < 50:
        return None
    # the chained INS velocity at each epoch; epochs across a gap start a new chain
    gaps = np.nonzero(np.diff(ep[:, 0]) > MAX_GAP_S)[0] + 1
    g = np.asarray(g, dtype=float)
    out = {w: [] for w in WINDOWS_S}
    for r in np.split(np.arange(ep.shape[0]), gaps):
        if r.size < 10:
            continue
        te, V = ep[r, 0], np.cumsum(ep[r, 1])
        gi = (g[:, 0] >= te[0]) & (g[:, 0] <= te[-1])
        tg, vd = g[gi, 0], g[gi, 1]
        if tg.size < 10:
            continue
        vi = np.interp(tg, te, V)
        for w in WINDOWS_S:
            j = np.searchsorted(tg, tg - w, side="left")
            ok = j < np.arange(tg.size)
            k, j = np.nonzero(ok)[0], j[ok]
            near = np.abs((tg[k] - tg[j]) - w) <= 0.15 * w + 0.1
            k, j = k[near], j[near]
            # no gap inside the window
            big = np.array([np.any(np.diff(tg[a:b + 1]) > MAX_GAP_S) for a, b in zip(j, k)], dtype=bool) \
                if k.size else np.zeros(0, dtype=bool)
            k, j = k[~big], j[~big]
            out[w].append((vi[k] - vi[j]) - (vd[k] - vd[j]))
    e = {w: np.concatenate(v) if v else np.zeros(0) for w, v in out.items()}
    if min(x.size for x in e.values()) < 20:
        return None
    return {"name": Path(path).name, "imu_hz": imu_hz, "gnss_hz": len(g) / max(g[-1, 0] - g[0, 0], 1e-9),
            "sd": {w: robust_sd(x) for w, x in e.items()}}


def fit(sd: dict, alpha: float) -> tuple[float, float]:
    """``(sigma_a, sigma_d)`` by least squares on the variances (both >= 0)."""
    ws = [w for w in WINDOWS_S if sd[w] == sd[w]]
    A = np.array([[gm_var(1.0, alpha, w), 2.0] for w in ws])
    y = np.array([sd[w] ** 2 for w in ws])
    # relative weights: each window's variance counts alike
    W = 1.0 / np.maximum(y, 1e-6)
    x, *_ = np.linalg.lstsq(A * W[:, None], y * W, rcond=None)
    x = np.maximum(x, 0.0)
    return math.sqrt(x[0]), math.sqrt(x[1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--min-imu-hz", type=float, default=20.0)
    args = ap.parse_args(argv)
    announce("ins_stats.py")
    paths = args.paths or [str(p) for ps in find_flights().values() for p in ps]
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as ex:
        rows = [r for r in ex.map(flight, paths, [args.min_imu_hz] * len(paths)) if r is not None]
    ins = config_from_dict({}).sensors.ins
    alpha, sigma = ins.alpha_a_per_s, ins.sigma_a_mps2
    print(f"{len(rows)} flights with a Doppler and the IMU at {args.min_imu_hz:g} Hz or more")
    print()
    print("Robust sd of e(W), m/s; the configured model (sigma_a {:g}, alpha_a {:g}) without the Doppler's "
          "noise on the last row; the fit per flight at that alpha_a:".format(sigma, alpha))
    print()
    print("| flight | IMU / GNSS Hz | " + " | ".join(f"W {w:g} s" for w in WINDOWS_S) + " | fit sigma_a / sigma_d |")
    print("|---|---|" + "---|" * len(WINDOWS_S) + "---|")
    fits = []
    for r in rows:
        sa, sdop = fit(r["sd"], alpha)
        fits.append(sa)
        print(f"| {r['name']} | {r['imu_hz']:.0f} / {r['gnss_hz']:.1f} | "
              + " | ".join(f"{r['sd'][w]:.3f}" for w in WINDOWS_S) + f" | {sa:.3f} / {sdop:.3f} |")
    med = {w: float(np.median([r["sd"][w] for r in rows])) for w in WINDOWS_S}
    print("| median over the flights | | " + " | ".join(f"{med[w]:.3f}" for w in WINDOWS_S) + " | |")
    print("| model (Doppler noise 0) | | " + " | ".join(f"{math.sqrt(gm_var(sigma, alpha, w)):.3f}"
                                                     for w in WINDOWS_S) + " | |")
    if fits:
        f = np.array(fits)
        print()
        print(f"fitted sigma_a at alpha_a {alpha:g}: median {np.median(f):.3f}, 90th percentile "
              f"{np.percentile(f, 90):.3f}, max {f.max():.3f} m/s^2")
    return 0


if __name__ == "__main__":
    sys.exit(main())
