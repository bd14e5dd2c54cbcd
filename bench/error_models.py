"""Error statistics of real baro and GNSS heights: what the filter models are sized from.

    python bench/error_models.py [--workers 2] [paths...]

For every real flight ``bench/realflights.py`` finds, with the autopilot's
own height as the common reference (it is smooth and continuous, whatever
its sensors), prints:

* ``baro white``: the short-term baro noise, std of the first differences of
  ``baro - autopilot`` divided by sqrt(2), at the baro's own rate, with that
  rate;
* ``baro-gnss D(tau)``: the structure function ``rms(d(t + tau) - d(t))`` of
  ``d = baro - GNSS`` resampled at 1 Hz, for tau = 1, 10, 60, 300 s: how far
  the two sensors wander apart over tau (a random walk grows as sqrt(tau), a
  Gauss-Markov error levels off at sqrt(2) sigma);
* ``gnss-ap D(tau)`` the same for ``GNSS - autopilot``;
* the receiver's reported vertical accuracy (median), when it reports one.

docs/error_models.md explains the method and the numbers chosen from it.
"""

from __future__ import annotations

import argparse
import math
import sys
from multiprocessing import get_context
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from realflights import find_flights  # noqa: E402

from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.samples import AutopilotHeight, BaroHeight, GnssHeight, Reboot  # noqa: E402

LAGS_S = (1, 10, 60, 300)


def _structure(t: np.ndarray, d: np.ndarray, lags=LAGS_S) -> dict:
    if t.size < 10:
        return {}
    grid = np.arange(t[0], t[-1], 1.0)
    if grid.size < 5:
        return {}
    r = np.interp(grid, t, d)
    # no interpolation across gaps longer than 3 s
    gap = np.interp(grid, t[1:], np.diff(t)) > 3.0
    r[gap] = np.nan
    out = {}
    for lag in lags:
        if grid.size > lag + 5:
            x = r[lag:] - r[:-lag]
            x = x[np.isfinite(x)]
            if x.size >= 5:
                out[lag] = float(np.sqrt(np.mean(x * x)))
    return out


def flight(path: str) -> dict:
    cfg = config_from_dict({})
    baro, gnss, ap, vacc = [], [], [], []
    try:
        for s in open_log(path, cfg.ingest):
            if isinstance(s, Reboot):
                break  # first boot only: one time base
            if isinstance(s, BaroHeight):
                baro.append((s.t_us * 1e-6, s.height_ref_m))
            elif isinstance(s, GnssHeight):
                gnss.append((s.t_us * 1e-6, s.height_ref_m))
                if s.sigma_m is not None:
                    vacc.append(s.sigma_m)
            elif isinstance(s, AutopilotHeight):
                ap.append((s.t_us * 1e-6, s.height_ref_m))
    except MavnavError as exc:
        return {"path": path, "error": str(exc)}
    out = {"path": path}
    b = np.array(baro).reshape(-1, 2)
    g = np.array(gnss).reshape(-1, 2)
    a = np.array(ap).reshape(-1, 2)
    if b.shape[0] > 20 and a.shape[0] > 20:
        r = b[:, 1] - np.interp(b[:, 0], a[:, 0], a[:, 1])
        dt = np.diff(b[:, 0])
        ok = (dt > 0) & (dt < 1.0)
        d = np.diff(r)[ok]
        if d.size > 10:
            mad = np.median(np.abs(d - np.median(d))) * 1.4826
            out["baro_white_m"] = float(np.std(d) / math.sqrt(2))
            out["baro_white_robust_m"] = float(mad / math.sqrt(2))
            out["baro_rate_hz"] = float(1.0 / np.median(dt[ok]))
    if b.shape[0] > 20 and g.shape[0] > 20:
        d = np.interp(g[:, 0], b[:, 0], b[:, 1]) - g[:, 1]
        out["baro_gnss"] = _structure(g[:, 0], d)
    if g.shape[0] > 20 and a.shape[0] > 20:
        d = g[:, 1] - np.interp(g[:, 0], a[:, 0], a[:, 1])
        out["gnss_ap"] = _structure(g[:, 0], d)
    if vacc:
        out["vacc_median_m"] = float(np.median(vacc))
    out["duration_s"] = float(b[-1, 0] - b[0, 0]) if b.shape[0] > 1 else 0.0
    return out


def _f(v, nd=2):
    return "-" if v is None else f"{v:.{nd}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    paths = [str(p) for p in args.paths] or [str(p) for ps in find_flights().values() for p in ps]
    if args.workers > 1:
        with get_context("spawn").Pool(args.workers) as pool:
            res = pool.map(flight, paths, chunksize=1)
    else:
        res = [flight(p) for p in paths]
    print("| flight | min | baro Hz | baro white m (robust) | baro-gnss D(1/10/60/300 s) m | gnss-ap D(1/10/60/300 s) m | v_acc m |")
    print("|---|---|---|---|---|---|---|")
    for r in res:
        if "error" in r:
            print(f"| {Path(r['path']).name} | error |")
            continue
        bg = r.get("baro_gnss", {})
        ga = r.get("gnss_ap", {})
        print("| %s | %.1f | %s | %s (%s) | %s | %s | %s |" % (
            Path(r["path"]).name, r["duration_s"] / 60, _f(r.get("baro_rate_hz"), 1), _f(r.get("baro_white_m")),
            _f(r.get("baro_white_robust_m")), "/".join(_f(bg.get(k)) for k in LAGS_S),
            "/".join(_f(ga.get(k)) for k in LAGS_S), _f(r.get("vacc_median_m"))))
    for key in ("baro_white_robust_m",):
        v = np.array([r[key] for r in res if key in r])
        if v.size:
            print(f"\n{key}: median {np.median(v):.2f}, 90th percentile {np.percentile(v, 90):.2f} over {v.size} flights")
    for key in ("baro_gnss", "gnss_ap"):
        for lag in LAGS_S:
            v = np.array([r[key][lag] for r in res if key in r and lag in r[key]])
            if v.size:
                print(f"{key} D({lag} s): median {np.median(v):.2f}, 90th percentile {np.percentile(v, 90):.2f} "
                      f"over {v.size} flights")
    med = {lag: np.median([r["gnss_ap"][lag] for r in res if lag in r.get("gnss_ap", {})])
           for lag in LAGS_S if any(lag in r.get("gnss_ap", {}) for r in res)}
    if len(med) >= 3:
        print("\n" + fit_lines(med))
    return 0


def structure_first_order(lag_s, sigma_m: float, tau_s: float):
    """D(lag) of a first-order Gauss-Markov error (stationary RMS sigma, correlation time tau)."""
    return np.sqrt(2.0 * sigma_m ** 2 * (1.0 - np.exp(-np.asarray(lag_s, float) / tau_s)))


def structure_second_order(lag_s, sigma_m: float, tau_b_s: float, tau_r_s: float):
    """D(lag) of a second-order error (two real poles: the error decays with tau_b, its rate with
    tau_r; stationary RMS sigma): autocorrelation (tau_b e^(-L/tau_b) - tau_r e^(-L/tau_r)) / (tau_b - tau_r)."""
    lag = np.asarray(lag_s, float)
    rho = (tau_b_s * np.exp(-lag / tau_b_s) - tau_r_s * np.exp(-lag / tau_r_s)) / (tau_b_s - tau_r_s)
    return np.sqrt(2.0 * sigma_m ** 2 * (1.0 - rho))


def fit_lines(med: dict) -> str:
    """Grid fits of both error models to the median GNSS - autopilot structure function (log error),
    and what each predicts between two 5 Hz fixes."""
    lags = np.array(sorted(med), float)
    target = np.array([med[k] for k in sorted(med)])
    sigmas = np.arange(0.5, 8.01, 0.25)

    def best(f, grids):
        out = None
        for p in ((s, *rest) for s in sigmas for rest in grids):
            err = float(np.sum((np.log(f(lags, *p)) - np.log(target)) ** 2))
            if out is None or err < out[0]:
                out = (err, p)
        return out

    e1, p1 = best(structure_first_order, [(t,) for t in (30, 60, 100, 150, 200, 300, 500, 1000, 2000)])
    e2, p2 = best(structure_second_order, [(tb, tr) for tb in (60, 100, 150, 200, 300, 500, 1000)
                                          for tr in (2, 5, 10, 15, 20, 30, 45, 60) if tr < tb])
    fmt = "/".join(f"{x:.2f}" for x in target)
    return "\n".join([
        f"fit to the median GNSS - autopilot D({'/'.join(f'{x:g}' for x in lags)} s) = {fmt} m (log error):",
        f"  first order: sigma {p1[0]:.2f} m, tau {p1[1]:g} s -> "
        f"{'/'.join(f'{x:.2f}' for x in structure_first_order(lags, *p1))} (error {e1:.3f}); "
        f"between 5 Hz fixes {structure_first_order(0.2, *p1):.3f} m",
        f"  second order: sigma {p2[0]:.2f} m, tau_b {p2[1]:g} s, tau_r {p2[2]:g} s -> "
        f"{'/'.join(f'{x:.2f}' for x in structure_second_order(lags, *p2))} (error {e2:.3f}); "
        f"rate RMS {p2[0] / math.sqrt(p2[1] * p2[2]):.3f} m/s; between 5 Hz fixes "
        f"{structure_second_order(0.2, *p2):.3f} m",
        f"  the filter's model today (first order, sigma 4 m, tau 300 s): "
        f"{'/'.join(f'{x:.2f}' for x in structure_first_order(lags, 4.0, 300.0))}; between 5 Hz fixes "
        f"{structure_first_order(0.2, 4.0, 300.0):.3f} m"])


if __name__ == "__main__":
    raise SystemExit(main())
