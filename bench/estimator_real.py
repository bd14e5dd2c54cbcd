"""The estimator on real flights: is each channel consistent with its own model?

    python bench/estimator_real.py [--workers 2] [--limit N] [--json out.json] [--set KEY=YAML] [paths...]

Runs the three channel filters alone (the epoch builder and the bank, every
measurement row used, no integrity decisions) over every real flight that
``bench/realflights.py`` finds, and prints per flight and in total the
evidence of issue 12:

* ``nu2``: the variance of each row's normalised innovation (baro row of
  the baro channel, GNSS row of the GNSS channel, rangefinder row of the
  rangefinder channel); a consistent model gives 1 (0.5-2 accepted). Also the
  share of innovations beyond 5 sigma;
* ``v3s``: the share of epochs where the GNSS (else baro) channel's vertical
  velocity is within 3 sigma of the autopilot's (sigma from the channel's own
  covariance, plus 0.1 m/s for the autopilot's own error);
  The autopilot's velocity is a yardstick only where it agrees with its own
  height: ``AP v self``, the RMS of its departure from its own height's
  rate over 1 s, is printed, and the count is also given over the flights
  where that stays within 0.3 m/s;
* ``used``: the share of GNSS and rangefinder samples that reached an epoch;
* ``sig>5``: the share of epochs after the first 10 s with a channel above
  5 m sigma, and the longest stretch of them in seconds: a channel carried
  across a gap in the log has an honest sigma that grows and comes back at
  the next sample; one that *stays* above 5 m (issue 12) has a stretch
  longer than SETTLE_S (the same 10 s the issue gives a start);
* ``rms``: each channel's height against the autopilot's (RMS, m).

Numbers are what the estimator does, good or bad.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from multiprocessing import get_context
from pathlib import Path
from typing import List, Optional, Sequence

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from realflights import find_flights, parse_set  # noqa: E402

from mavnav.bank import BARO, GNSS, RNG, ChannelBank  # noqa: E402
from mavnav.channel import Model  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.epochs import EpochBuilder, EpochStart  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402
from mavnav.ingest import open_log  # noqa: E402
from mavnav.samples import AutopilotHeight, GnssHeight, RangeHeight, Reboot  # noqa: E402

AP_VEL_SIGMA_MPS = 0.1
# The autopilot's logged velocity is a yardstick only where it agrees with its
# own height: its departure from its own height's rate over 1 s (RMS) is
# printed per flight, and the velocity check is also counted over the flights
# where it stays within AP_SELF_MAX_MPS (old ArduCopter inertial navigation:
# CTUN.CRt / EKF1.VD 1.0-2.5 m/s RMS off their own height's rate on the 2014
# Erle logs and dkla).
AP_SELF_WINDOW_S = 1.0
AP_SELF_MAX_MPS = 0.3
SIGMA_LIMIT_M = 5.0
SETTLE_S = 10.0
ROWS = (("baro", BARO, 0), ("gnss", GNSS, 1), ("rng", RNG, 1))


class _Acc:
    """Running sums of one flight (one boot at a time; reboots restart the filters)."""

    def __init__(self):
        self.nu2 = {k: [] for k, _, _ in ROWS}
        self.vel_in = self.vel_n = 0
        self.ap = []  # (t_s, height, vel): the autopilot's own samples, for its self-consistency
        self.sig_hi = self.sig_n = 0
        self.hi_since: Optional[int] = None  # the current stretch above SIGMA_LIMIT_M began
        self.hi_longest_s = 0.0
        self.err2 = {c: [] for c in ("gnss", "rng", "baro")}
        self.epochs = 0


def flight(path: str, cfg_dict: Optional[dict] = None) -> dict:
    cfg = config_from_dict(cfg_dict or {})
    model = Model.from_config(cfg)
    out = {"path": path}
    try:
        src = open_log(path, cfg.ingest)
        acc = _Acc()
        builder = EpochBuilder(cfg)
        bank = ChannelBank(model, track_cross=False)
        ap_h = ap_v = math.nan
        ap_t = None
        t0 = None
        n_in = {"gnss": 0, "rng": 0}
        used0 = {"gnss": 0, "rng": 0}
        for s in src:
            if isinstance(s, AutopilotHeight):
                ap_h, ap_v, ap_t = s.height_ref_m, s.vel_up_mps, s.t_us
                if getattr(s, "boot", 0) == 0:
                    acc.ap.append((s.t_us * 1e-6, s.height_ref_m, s.vel_up_mps))
                continue
            if isinstance(s, GnssHeight):
                n_in["gnss"] += 1
            elif isinstance(s, RangeHeight):
                n_in["rng"] += 1
            elif isinstance(s, Reboot):
                for k in used0:
                    used0[k] += builder.counters[f"{k}_used"]
                builder = EpochBuilder(cfg)
                bank = ChannelBank(model, track_cross=False)
                ap_t, t0 = None, None
                acc.hi_since = None
                continue
            for ep in builder.push(s):
                if isinstance(ep, EpochStart):
                    bank.start(ep.t_us, ep.baro_m)
                    t0 = ep.t_us
                    continue
                st = bank.step(ep)
                acc.epochs += 1
                for name, c, slot in ROWS:
                    v = st.innovation_var[c, slot]
                    if v == v and v > 0:
                        acc.nu2[name].append(st.innovation[c, slot] ** 2 / v)
                settled = (ep.t_us - t0) * 1e-6 > SETTLE_S
                if settled:
                    acc.sig_n += 1
                    if any(bank.P[c, 0, 0] > SIGMA_LIMIT_M ** 2 for c in (GNSS, RNG, BARO)):
                        acc.sig_hi += 1
                        if acc.hi_since is None:
                            acc.hi_since = ep.t_us
                        acc.hi_longest_s = max(acc.hi_longest_s, (ep.t_us - acc.hi_since) * 1e-6)
                    else:
                        acc.hi_since = None
                fresh = ap_t is not None and abs(ep.t_us - ap_t) < 200_000
                if settled and fresh:
                    if ap_v == ap_v:
                        c = GNSS if ep.gnss is not None or builder.counters["gnss_used"] else BARO
                        lim = 3.0 * math.sqrt(bank.P[c, 1, 1] + AP_VEL_SIGMA_MPS ** 2)
                        acc.vel_n += 1
                        acc.vel_in += abs(bank.x[c, 1] - ap_v) <= lim
                    if ap_h == ap_h:
                        for name, c in (("gnss", GNSS), ("rng", RNG), ("baro", BARO)):
                            acc.err2[name].append((bank.x[c, 0] - ap_h) ** 2)
        for k in used0:
            used0[k] += builder.counters[f"{k}_used"]
    except MavnavError as exc:
        out["error"] = str(exc)
        return out
    out["epochs"] = acc.epochs
    out["nu2"] = {k: (float(np.mean(v)) if len(v) >= 20 else None) for k, v in acc.nu2.items()}
    out["beyond5"] = {k: (float(np.mean(np.asarray(v) > 25.0)) if len(v) >= 20 else None) for k, v in acc.nu2.items()}
    out["ap_self_mps"] = ap_self_consistency(acc.ap)
    out["v3s"] = acc.vel_in / acc.vel_n if acc.vel_n else None
    out["used"] = {k: (used0[k] / n_in[k] if n_in[k] else None) for k in n_in}
    out["n_in"] = n_in
    out["sig_hi"] = acc.sig_hi / acc.sig_n if acc.sig_n else None
    out["sig_hi_longest_s"] = acc.hi_longest_s
    out["rms"] = {k: (math.sqrt(float(np.mean(v))) if v else None) for k, v in acc.err2.items()}
    return out


def ap_self_consistency(ap: list) -> Optional[float]:
    """RMS of the autopilot's logged vertical velocity (mean over each span)
    less its own height's rate over ``AP_SELF_WINDOW_S``; None without both."""
    a = np.asarray([r for r in ap if r[2] == r[2] and r[1] == r[1]], float).reshape(-1, 3)
    if len(a) < 20:
        return None
    t, h, v = a[:, 0], a[:, 1], a[:, 2]
    k = np.minimum(np.searchsorted(t, t + AP_SELF_WINDOW_S), len(t) - 1)
    span = t[k] - t
    ok = (span > 0.5 * AP_SELF_WINDOW_S) & (span < 2.0 * AP_SELF_WINDOW_S)
    if ok.sum() < 10:
        return None
    d = (h[k] - h)[ok] / span[ok] - 0.5 * (v + v[k])[ok]
    return float(np.sqrt(np.mean(d * d)))


def _fmt(v, nd=2) -> str:
    return "-" if v is None else f"{v:.{nd}f}"


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:.1f}"


def report(results: List[dict]) -> str:
    lines = ["| flight | epochs | nu2 baro | nu2 gnss | nu2 rng | >5s baro/gnss/rng % | v in 3s % | "
             "AP v self m/s | gnss used % | rng used % | sig>5m % / longest s | rms gnss/rng/baro m |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        name = Path(r["path"]).name
        if "error" in r:
            lines.append(f"| {name} | error: {r['error'][:60]} |")
            continue
        b5 = r["beyond5"]
        lines.append("| %s | %d | %s | %s | %s | %s/%s/%s | %s | %s | %s | %s | %s | %s/%s/%s |" % (
            name, r["epochs"], _fmt(r["nu2"]["baro"]), _fmt(r["nu2"]["gnss"]), _fmt(r["nu2"]["rng"]),
            _pct(b5["baro"]), _pct(b5["gnss"]), _pct(b5["rng"]), _pct(r["v3s"]), _fmt(r.get("ap_self_mps")),
            _pct(r["used"]["gnss"]), _pct(r["used"]["rng"]),
            f'{_pct(r["sig_hi"])} / {r.get("sig_hi_longest_s", 0.0):.1f}',
            _fmt(r["rms"]["gnss"], 1), _fmt(r["rms"]["rng"], 1), _fmt(r["rms"]["baro"], 1)))
    ok = [r for r in results if "error" not in r]

    def count(pred) -> str:
        n = sum(1 for r in ok if pred(r))
        return f"{n}/{len(ok)}"

    def in_band(v):
        return v is None or 0.5 <= v <= 2.0

    lines.append("")
    lines.append(f"flights with every row's nu2 in 0.5-2: {count(lambda r: all(in_band(v) for v in r['nu2'].values()))}")
    def v_ok(r):
        return r["v3s"] is None or r["v3s"] >= 0.99

    ref = [r for r in ok if r.get("ap_self_mps") is None or r["ap_self_mps"] <= AP_SELF_MAX_MPS]
    lines.append(f"flights with velocity within 3 sigma in >= 99 % of epochs: {count(v_ok)}; "
                 f"{sum(1 for r in ref if v_ok(r))}/{len(ref)} of those whose autopilot velocity is a usable "
                 f"reference (within {AP_SELF_MAX_MPS:g} m/s RMS of its own height's rate over "
                 f"{AP_SELF_WINDOW_S:g} s)")
    lines.append(f"flights using >= 95 % of GNSS and rangefinder samples: "
                 f"{count(lambda r: all(v is None or v >= 0.95 for v in r['used'].values()))}")
    lines.append(f"flights with no channel above 5 m sigma after 10 s: {count(lambda r: not r['sig_hi'])}; "
                 f"with none staying above it longer than {SETTLE_S:g} s: "
                 f"{count(lambda r: r.get('sig_hi_longest_s', 0.0) <= SETTLE_S)}")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--json", dest="json_out")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=YAML",
                    help="a configuration setting by its dotted key (e.g. sensors.gnss.gm_tau_s=1000); repeatable")
    args = ap.parse_args(argv)
    job = functools.partial(flight, cfg_dict=parse_set(args.set))
    if args.paths:
        paths = [str(p) for p in args.paths]
    else:
        groups = find_flights()
        paths = [str(p) for ps in groups.values() for p in ps]
        print(", ".join(f"{k}: {len(v)}" for k, v in groups.items()))
    if args.limit:
        paths = paths[: args.limit]
    t0 = time.perf_counter()
    if args.workers > 1:
        with get_context("spawn").Pool(args.workers) as pool:
            results = pool.map(job, paths, chunksize=1)
    else:
        results = [job(p) for p in paths]
    print(report(results))
    print(f"\n{len(results)} flights in {time.perf_counter() - t0:.0f} s")
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
