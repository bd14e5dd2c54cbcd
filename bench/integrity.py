"""Integrity scorecard: Monte Carlo over fault kind x magnitude x seed, three contenders.

Contenders, on the same samples in the same run:

* ``paper``: mavnav, ``monitor.mode: paper`` (the paper's Fig. 4 logic);
* ``adaptive``: mavnav, ``monitor.mode: adaptive`` (the default);
* ``baseline``: ``bench/autopilot_baseline.py``, a small model of what
  ArduPilot EKF3 / PX4 EKF2 do with height (one filter, 5-sigma gates, stale
  fallback, a source "fails" after 5 s of gate failures).

Every log is read once by :class:`mavnav.ingest.TlogSource`; the resulting
list of samples is fed to all three, so they see identical data.

Data
----
* **sim** (the fault grid): 60 s PX4 flights with the rates, sensors and
  home of ``config/scenarios/px4_landing_nominal.yaml`` (IMU 100 Hz, baro
  25 Hz, GNSS 10 Hz, rangefinder 20 Hz) but starting on the ground: odd
  seeds an approach (take-off, climb to 35 m, hold, descend to 2 m), even
  seeds a take-off and hover at 15 m. ``seed`` = 1..N, one fault per run,
  onset drawn uniformly in [15, 30] s (vehicle time) from the seed. Filter
  noise config: the scenario's own (``Scenario.filter_sensors()``), for all
  three contenders. Each seed also runs fault-free.
* **landing**: ``px4_landing_nominal.yaml`` as shipped (it starts in the air
  at 35 m: the monitor is switched on in flight), fault-free, N/2 seeds.
* **long**: fault-free PX4 flights of ``--long-minutes`` (hover at 15 m and
  a step profile, alternately), for false alarms per hour and fault-free RMS.
* **real**: the ArduPilot SITL log ``../shared/tlogs/sitl/copter_rangefinder_nominal.tlog``
  (ArduCopter 4.3.7, 233 s) with faults injected by ``mavnav.sim.inject_bytes``,
  onset drawn uniformly in [80, 200] s of its boot clock. Filter noise
  config: mavnav's defaults (the SITL's sensor noise is not known); truth
  from its ``.truth.csv`` (``true_alt_msl_m`` minus the home altitude the
  log reports).

Fault grid (per seed): GNSS step, rangefinder step (``rng_spikes`` with
probability 1: every reading offset) and baro step at 3, 5 and 8 sigma of
the channel difference; GNSS and baro ramps at 0.5 m/s; an accelerometer
bias step of 0.3 m/s^2; a stuck rangefinder. Steps last 10 s, ramps 12 s
(to 6 m).

"Sigma of the channel difference" is the monitor's own: in the fault-free
run of the same seed, the adaptive monitor's comparison threshold divided
by its ``k`` (``threshold = k sqrt(P_a + P_b - 2 P_ab)``, sensor-variance
floor included), median over the 2 s before the onset. GNSS: the GNSS vs
baro+INS pair (the paper's ``d1``); rangefinder: rangefinder vs baro+INS
(``d2``); baro+INS: the larger of the two (a baro fault must stand out
against both to be isolated 2-of-3).

Metrics: ``bench/scoremetrics.py`` (detection: the first transition into
``alarm`` of any source within the fault window; time-to-alarm from the
onset; isolation: the blamed source is the fault's; false alarms per hour:
alarm transitions on fault-free runs per hour of vehicle time; RMS of the
fused height against truth on the 10 Hz truth grid, sample-and-hold,
fault-free runs after the first 10 s, and inside fault windows).

Usage::

    .venv/bin/python bench/integrity.py            # default size (a few minutes on 2 cores)
    .venv/bin/python bench/integrity.py --quick    # tiny smoke run
    .venv/bin/python bench/integrity.py --seeds 20 --real-seeds 5 --workers 2
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import scoremetrics as sm  # noqa: E402
from autopilot_baseline import BaselineConfig, run_baseline  # noqa: E402

from mavnav.config import SensorsConfig, config_from_dict  # noqa: E402
from mavnav.ingest import TlogSource  # noqa: E402
from mavnav.monitor.levels import normal_k  # noqa: E402
from mavnav.pipeline import run  # noqa: E402
from mavnav.samples import ReferenceSet  # noqa: E402
from mavnav.sim import Fault, inject_bytes, scenario_from_dict, simulate  # noqa: E402
from mavnav.sim.simulate import read_truth_csv  # noqa: E402
from mavnav.sinks.base import Sink  # noqa: E402

CONTENDERS = ("paper", "adaptive", "baseline")
SIM_SCENARIO = ROOT / "config" / "scenarios" / "px4_landing_nominal.yaml"
REAL_LOG = (ROOT / ".." / "shared" / "tlogs" / "sitl" / "copter_rangefinder_nominal.tlog").resolve()
REAL_TRUTH = REAL_LOG.with_name("copter_rangefinder_nominal.truth.csv")
SETTLE_S = 10.0  # fault-free RMS excludes the first seconds of a run (convergence)
STEP_MULTS = (3.0, 5.0, 8.0)
RAMP_RATE = 0.5
STEP_DURATION_S = 10.0
RAMP_DURATION_S = 12.0


# ---------------------------------------------------------------- fault grid


@dataclass(frozen=True)
class Case:
    """One row of the grid: a fault kind and a magnitude rule."""

    label: str
    kind: str
    source: str
    sigma_mult: Optional[float] = None  # magnitude = mult x sigma of the channel difference
    magnitude: Optional[float] = None  # absolute magnitude (ramps, accel)
    probability: Optional[float] = None
    duration_s: float = STEP_DURATION_S
    target: Optional[str] = None  # "step" or "ramp": which adaptive target it counts for


def fault_cases() -> List[Case]:
    out = []
    for kind, src, name in (("gnss_step", "gnss", "gnss step"), ("rng_spikes", "rangefinder", "rng step"),
                            ("baro_step", "baro_ins", "baro step")):
        for m in STEP_MULTS:
            out.append(Case(f"{name} {m:g}σ", kind, src, sigma_mult=m,
                            probability=1.0 if kind == "rng_spikes" else None, target="step"))
    out.append(Case(f"gnss ramp {RAMP_RATE:g} m/s", "gnss_ramp", "gnss", magnitude=RAMP_RATE,
                    duration_s=RAMP_DURATION_S, target="ramp"))
    out.append(Case(f"baro ramp {RAMP_RATE:g} m/s", "baro_ramp", "baro_ins", magnitude=RAMP_RATE,
                    duration_s=RAMP_DURATION_S, target="ramp"))
    out.append(Case("accel bias 0.3 m/s²", "accel_bias_step", "baro_ins", magnitude=0.3))
    out.append(Case("rng stuck", "rng_stuck", "rangefinder"))
    return out


def sigma_for(case: Case, sig: Dict[str, float]) -> float:
    if case.source == "gnss":
        return sig["gnss"]
    if case.source == "rangefinder":
        return sig["rangefinder"]
    return max(sig["gnss"], sig["rangefinder"])


def make_fault(case: Case, onset_s: float, sig: Dict[str, float], seed: int) -> dict:
    d = {"kind": case.kind, "onset_s": round(onset_s, 3), "duration_s": case.duration_s}
    if case.sigma_mult is not None:
        d["magnitude"] = round(case.sigma_mult * sigma_for(case, sig), 4)
    elif case.magnitude is not None:
        d["magnitude"] = case.magnitude
    if case.probability is not None:
        d["probability"] = case.probability
    d["seed"] = seed
    return d


def onset_for(dataset: str, seed: int, case_index: int) -> float:
    rng = np.random.default_rng([seed, 7919, case_index])
    return float(rng.uniform(15.0, 30.0) if dataset == "sim" else rng.uniform(80.0, 200.0))


# ---------------------------------------------------------------- running the contenders


class _Collect(Sink):
    """Fused height per epoch, and the comparison sigmas (threshold / k)."""

    name = "collect"

    def __init__(self, k: float) -> None:
        self.k = k
        self.t: List[float] = []
        self.h: List[float] = []
        self.sig_g: List[float] = []  # gnss vs baro+INS
        self.sig_r: List[float] = []  # rangefinder vs baro+INS

    def epoch(self, r) -> None:
        self.t.append(r.t_s)
        self.h.append(r.height_fused_m)
        p_gb, p_rb = r.pairs[1], r.pairs[2]
        self.sig_g.append(p_gb.threshold_m / self.k if p_gb.valid else math.nan)
        self.sig_r.append(p_rb.threshold_m / self.k if p_rb.valid else math.nan)


def run_all(samples: list, sensors: SensorsConfig, bcfg: BaselineConfig) -> Dict[str, dict]:
    """The three contenders on one list of samples: heights and alarms each."""
    out = {}
    for mode in ("paper", "adaptive"):
        cfg = config_from_dict({"sensors": sensors.model_dump(), "monitor": {"mode": mode}})
        sink = _Collect(normal_k(cfg.monitor.false_alarm_prob))
        summary = run(samples, cfg, [sink])
        out[mode] = {"t": np.asarray(sink.t), "h": np.asarray(sink.h, dtype=float), "alarms": list(summary.alarms),
                     "sig_g": np.asarray(sink.sig_g), "sig_r": np.asarray(sink.sig_r)}
    b = run_baseline(samples, sensors, bcfg)
    out["baseline"] = {"t": b.t_s, "h": b.height_m, "alarms": b.alarms}
    return out


def ingest(data: bytes) -> list:
    fd, path = tempfile.mkstemp(suffix=".tlog", prefix="mavnav-score-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        return list(TlogSource(path, config_from_dict({}).ingest))
    finally:
        os.unlink(path)


def sample_span_s(samples: list) -> float:
    ts = [s.t_us for s in samples if getattr(s, "t_us", None) is not None]
    return (max(ts) - min(ts)) * 1e-6 if ts else 0.0


# ---------------------------------------------------------------- one job


@dataclass
class JobResult:
    dataset: str  # "sim", "long", "real"
    seed: int
    case: Optional[str]  # None: fault-free
    fault: Optional[dict]
    span_s: float
    per: Dict[str, dict] = field(default_factory=dict)  # contender -> metrics
    sigmas: Optional[dict] = None  # fault-free runs: (t, sig_g, sig_r) of the adaptive monitor
    wall_s: float = 0.0


def _load_sim_dict() -> dict:
    return yaml.safe_load(SIM_SCENARIO.read_text())


def base_flight(seed: int) -> dict:
    """The fault grid's flight (ground start, PX4 rates and sensors of px4_landing_nominal).

    Odd seeds: an approach (take-off, climb to 35 m at 1.5 m/s, hold 8 s,
    descend to 2 m); even seeds: take-off and hover at 15 m.
    """
    d = _load_sim_dict()
    d["faults"] = []
    if seed % 2:
        d["name"] = f"approach_{seed}"
        d["trajectory"] = {"kind": "steps", "start_height_m": 0.0, "heights_m": [35.0, 2.0], "hold_s": 8.0,
                           "vertical_speed_mps": 1.5, "heading_deg": 35.0}
    else:
        d["name"] = f"hover_{seed}"
        d["trajectory"] = {"kind": "hover", "height_m": 15.0, "takeoff": True, "ground_s": 3.0,
                           "climb_speed_mps": 2.0, "wander_m": 0.3, "heading_deg": 120.0}
    return d


def _long_dict(seed: int, minutes: float) -> dict:
    d = _load_sim_dict()
    d["name"] = f"long_{seed}"
    d["duration_s"] = minutes * 60.0
    d["faults"] = []
    if seed % 2:
        d["trajectory"] = {"kind": "hover", "height_m": 15.0, "takeoff": True, "ground_s": 3.0,
                           "wander_m": 0.5, "wander_period_s": 25.0}
    else:
        rng = np.random.default_rng([seed, 31])
        n = int(minutes * 60 / 25) + 2
        d["trajectory"] = {"kind": "steps", "start_height_m": 0.0,
                           "heights_m": [float(round(h, 1)) for h in rng.uniform(3.0, 35.0, n)],
                           "hold_s": 15.0, "vertical_speed_mps": 1.5}
    return d


def scenario_dict(dataset: str, seed: int, long_minutes: float = 10.0) -> dict:
    if dataset == "sim":
        return base_flight(seed)
    if dataset == "landing":
        d = _load_sim_dict()  # px4_landing_nominal as shipped: starts in the air at 35 m
        d["faults"] = []
        return d
    return _long_dict(seed, long_minutes)


def _truth_real(samples: list) -> Tuple[np.ndarray, np.ndarray]:
    tr = read_truth_csv(REAL_TRUTH)
    ref = None
    for s in samples:
        if isinstance(s, ReferenceSet) and s.alt_ref_msl_m is not None:
            ref = s.alt_ref_msl_m
            break
    if ref is None:
        raise RuntimeError("the real log carries no home altitude")
    return np.asarray(tr["t_s"], dtype=float), np.asarray(tr["true_alt_msl_m"], dtype=float) - ref


def job(spec: dict) -> JobResult:
    t_wall = time.perf_counter()
    dataset, seed = spec["dataset"], spec["seed"]
    fault = spec.get("fault")
    bcfg = BaselineConfig(fail_s=spec.get("baseline_fail_s", 5.0))
    if dataset in ("sim", "long", "landing"):
        d = scenario_dict(dataset, seed, spec["long_minutes"])
        d["faults"] = [] if fault is None else [{k: v for k, v in fault.items() if k != "seed"}]
        scn = scenario_from_dict(d)
        res = simulate(scn, seed=seed)
        samples = ingest(res.tlog)
        sensors = scn.filter_sensors()
        if spec.get("rng_scale_frac") is not None:  # override of the rangefinder's scale-error sigma
            sensors = sensors.model_copy(update={"rangefinder": sensors.rangefinder.model_copy(
                update={"scale_sigma_frac": spec["rng_scale_frac"]})})
        t_truth = np.asarray(res.truth["t_s"], dtype=float)
        h_truth = np.asarray(res.truth["true_height_ref_m"], dtype=float)
    else:
        data = REAL_LOG.read_bytes()
        if fault is not None:
            data, _report = inject_bytes(data, [Fault.model_validate(fault)])
        samples = ingest(data)
        sensors = SensorsConfig()
        t_truth, h_truth = _truth_real(samples)
    outs = run_all(samples, sensors, bcfg)
    r = JobResult(dataset, seed, spec.get("case"), fault, sample_span_s(samples))
    for name, o in outs.items():
        m: dict = {"alarms": [(a.t_s, a.source, a.state, a.previous, a.reason) for a in sm.alarm_onsets(o["alarms"])]}
        if fault is None:
            e, nan = sm.height_errors(o["t"], o["h"], t_truth, h_truth, windows=[(t_truth[0] + SETTLE_S
                                                                                  if dataset != "real" else -1e9, 1e18)])
            m["ff_ss"], m["ff_n"], m["ff_nan"] = float(np.sum(e * e)), int(e.size), nan
            m["fa"] = sm.false_alarms(o["alarms"])
        else:
            on, end = fault["onset_s"], fault["onset_s"] + fault["duration_s"]
            det = sm.detect(o["alarms"], on, end, spec["source"])
            m["det"] = det
            e, nan = sm.height_errors(o["t"], o["h"], t_truth, h_truth, windows=[(on, end)])
            m["f_ss"], m["f_n"], m["f_nan"] = float(np.sum(e * e)), int(e.size), nan
            m["f_max"] = float(np.max(np.abs(e))) if e.size else math.nan
        r.per[name] = m
    if fault is None:
        a = outs["adaptive"]
        r.sigmas = {"t": a["t"][::5], "gnss": a["sig_g"][::5], "rangefinder": a["sig_r"][::5]}
    r.wall_s = time.perf_counter() - t_wall
    return r


def sigma_at(sig: dict, onset_s: float) -> Dict[str, float]:
    t = sig["t"]
    m = (t >= onset_s - 2.0) & (t <= onset_s)
    out = {}
    for k in ("gnss", "rangefinder"):
        v = sig[k][m]
        v = v[np.isfinite(v)]
        if v.size == 0:  # fall back to the whole run
            v = sig[k][np.isfinite(sig[k])]
        out[k] = float(np.median(v)) if v.size else math.nan
    return out


# ---------------------------------------------------------------- driver


def run_jobs(specs: List[dict], workers: int) -> List[JobResult]:
    if workers <= 1:
        return [job(s) for s in specs]
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    with ctx.Pool(workers) as pool:
        return list(pool.imap(job, specs, chunksize=1))


def fmt(v: float, nd: int = 2, unit: str = "") -> str:
    if v is None or not (v == v):
        return "-"
    if math.isinf(v):
        return "inf"
    return f"{v:.{nd}f}{unit}"


@dataclass
class Agg:
    ttas: List[float] = field(default_factory=list)
    n: int = 0
    detected: int = 0
    isolated: int = 0
    ss: float = 0.0
    cnt: int = 0
    nan: int = 0
    mags: List[float] = field(default_factory=list)
    max_err: float = 0.0


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=6, help="simulated seeds per fault case (default 6)")
    ap.add_argument("--real-seeds", type=int, default=2, help="injections per fault case into the SITL log (default 2)")
    ap.add_argument("--long-runs", type=int, default=4, help="long fault-free simulated flights (default 4)")
    ap.add_argument("--long-minutes", type=float, default=10.0, help="minutes per long flight (default 10)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--baseline-fail-s", type=float, default=5.0,
                    help="baseline: gate failures this long = source failure (EKF3/EKF2: 5 s)")
    ap.add_argument("--rng-scale-frac", type=float, default=None,
                    help="sim only: override rangefinder.scale_sigma_frac of Scenario.filter_sensors() "
                         "(which keeps mavnav's default 0.03 though the simulated rangefinder has no scale error)")
    ap.add_argument("--quick", action="store_true", help="tiny run: 1 seed, 1 injection, 1 short long flight")
    ap.add_argument("--no-real", action="store_true", help="skip the injected SITL log")
    args = ap.parse_args(argv)
    if args.quick:
        args.seeds, args.real_seeds, args.long_runs, args.long_minutes = 1, 0, 1, 2.0
    if not REAL_LOG.exists():
        print(f"note: {REAL_LOG} not found: the real-log part is skipped")
        args.no_real = True
    t0 = time.perf_counter()
    cases = fault_cases()
    common = {"baseline_fail_s": args.baseline_fail_s, "long_minutes": args.long_minutes,
              "rng_scale_frac": args.rng_scale_frac}

    # phase 1: fault-free runs (false alarms, fault-free RMS, the sigmas that scale the steps)
    specs = [dict(common, dataset="sim", seed=s) for s in range(1, args.seeds + 1)]
    specs += [dict(common, dataset="landing", seed=s) for s in range(1, max(1, args.seeds // 2) + 1)]
    specs += [dict(common, dataset="long", seed=1000 + s) for s in range(1, args.long_runs + 1)]
    if not args.no_real:
        specs.append(dict(common, dataset="real", seed=0))
    free = run_jobs(specs, args.workers)
    sig_by = {(r.dataset, r.seed): r.sigmas for r in free if r.dataset in ("sim", "real")}

    # phase 2: fault runs
    specs = []
    datasets = [("sim", range(1, args.seeds + 1))]
    if not args.no_real and args.real_seeds > 0:
        datasets.append(("real", range(1, args.real_seeds + 1)))
    for dataset, seeds in datasets:
        for seed in seeds:
            sig_src = sig_by[("sim", seed)] if dataset == "sim" else sig_by[("real", 0)]
            for ci, case in enumerate(cases):
                on = onset_for(dataset, seed, ci)
                sig = sigma_at(sig_src, on)
                f = make_fault(case, on, sig, seed)
                specs.append(dict(common, dataset=dataset, seed=seed, case=case.label, source=case.source,
                                  fault=f, sigma=sigma_for(case, sig)))
    faulted = run_jobs(specs, args.workers)
    wall = time.perf_counter() - t0
    report(args, cases, free, faulted, wall)
    return 0


def report(args, cases: List[Case], free: List[JobResult], faulted: List[JobResult], wall: float) -> None:
    P = print
    case_by = {c.label: c for c in cases}
    P("=" * 100)
    P("mavnav integrity scorecard: paper vs adaptive vs autopilot baseline (EKF3/EKF2-like, "
      f"5-sigma gates, fail after {args.baseline_fail_s:g} s)")
    P(f"sim: 60 s ground-start approach/hover flights with the rates, sensors and home of "
      f"{SIM_SCENARIO.relative_to(ROOT)} (PX4), seeds 1..{args.seeds}, filter noise = "
      "Scenario.filter_sensors()"
      + ("" if args.rng_scale_frac is None else f" with rangefinder.scale_sigma_frac={args.rng_scale_frac:g}")
      + "; "
      f"real: {REAL_LOG.name} + inject_bytes, {0 if args.no_real else args.real_seeds} injection(s) per case, "
      "filter noise = mavnav defaults")
    P("σ = the adaptive monitor's sigma of the channel difference at onset (threshold/k, fault-free run)")
    for dataset in ("sim", "real"):
        rows = [r for r in faulted if r.dataset == dataset]
        if not rows:
            continue
        P("-" * 100)
        P(f"[{dataset}] faults: Pd = detected/runs, TTA = time to the first alarm (s), iso = correct source / detected,"
          " RMS/max = fused height error in the fault window (m)")
        P(f"{'case':<22}{'magnitude':>16}  {'contender':<9}{'Pd':>7}{'TTA med':>9}{'TTA p95':>9}{'iso':>7}"
          f"{'RMS':>7}{'max':>7}  blamed when wrong")
        aggs: Dict[Tuple[str, str], Agg] = defaultdict(Agg)
        wrong: Dict[Tuple[str, str], Dict[str, int]] = defaultdict(lambda: defaultdict(int))
        for r in rows:
            for name in CONTENDERS:
                m = r.per[name]
                a = aggs[(r.case, name)]
                a.n += 1
                d = m["det"]
                if d.detected:
                    a.detected += 1
                    a.ttas.append(d.tta_s)
                    if d.isolated:
                        a.isolated += 1
                    else:
                        wrong[(r.case, name)]["+".join(d.first_sources)] += 1
                a.ss += m["f_ss"]
                a.cnt += m["f_n"]
                a.nan += m["f_nan"]
                if m["f_max"] == m["f_max"]:
                    a.max_err = max(a.max_err, m["f_max"])
                a.mags.append(r.fault.get("magnitude", math.nan) if r.fault.get("magnitude") is not None else math.nan)
        for case in cases:
            for i, name in enumerate(CONTENDERS):
                a = aggs.get((case.label, name))
                if a is None:
                    continue
                med, p95 = sm.tta_stats(a.ttas)
                mags = np.asarray(a.mags, dtype=float)
                if case.kind == "rng_stuck":
                    mag = "held reading"
                elif np.all(np.isnan(mags)):
                    mag = "-"
                elif case.sigma_mult is not None:
                    mag = f"{np.nanmin(mags):.2f}-{np.nanmax(mags):.2f} m"
                else:
                    unit = " m/s²" if case.kind == "accel_bias_step" else " m/s" if "ramp" in case.kind else " m"
                    mag = f"{np.nanmean(mags):g}{unit}"
                w = ", ".join(f"{k} x{v}" for k, v in sorted(wrong[(case.label, name)].items()))
                P(f"{case.label if i == 0 else '':<22}{mag if i == 0 else '':>16}  {name:<9}"
                  f"{a.detected:>3}/{a.n:<3}{fmt(med):>9}{fmt(p95):>9}"
                  f"{(str(a.isolated) + '/' + str(a.detected)):>7}"
                  f"{fmt(math.sqrt(a.ss / a.cnt) if a.cnt else math.nan):>7}{fmt(a.max_err):>7}  {w}")

    # fault-free
    P("-" * 100)
    P("fault-free: false alarms (alarm transitions) per hour of vehicle time, fused RMS vs truth "
      f"(sim: after the first {SETTLE_S:g} s)")
    P(f"{'data':<34}{'contender':<10}{'hours':>7}{'alarms':>8}{'FA/h':>8}{'95% up':>8}{'RMS m':>8}  ICAO (vertical RMS)")
    groups = [("sim grid flights (PX4, 60 s)", ["sim"]), ("sim in-air landing (PX4, 60 s)", ["landing"]),
              ("sim long (PX4)", ["long"]), ("sim all (PX4)", ["sim", "landing", "long"]),
              ("real SITL log (ArduPilot)", ["real"])]
    ff = {}
    for label, dsets in groups:
        rows = [r for r in free if r.dataset in dsets]
        if not rows:
            continue
        hours = sum(r.span_s for r in rows) / 3600.0
        for name in CONTENDERS:
            fa = sum(r.per[name]["fa"] for r in rows)
            ss = sum(r.per[name]["ff_ss"] for r in rows)
            n = sum(r.per[name]["ff_n"] for r in rows)
            rm = math.sqrt(ss / n) if n else math.nan
            ff[(label, name)] = (fa, hours, rm)
            P(f"{label:<34}{name:<10}{hours:>7.3f}{fa:>8}{fmt(sm.per_hour(fa, hours * 3600)):>8}"
              f"{fmt(sm.poisson_upper_95(fa, hours * 3600)):>8}{fmt(rm, 3):>8}  {sm.icao_band(rm)}")
    P("ICAO vertical RMS bands (MODEL.md): " + ", ".join(f"{n} {lo:g}-{hi:g} m" for n, lo, hi in sm.ICAO_BANDS))
    fa_alarms = [(r.dataset, r.seed, name, a) for r in free for name in CONTENDERS for a in r.per[name]["alarms"]]
    if fa_alarms:
        P("false alarms seen:")
        for ds, seed, name, a in fa_alarms[:20]:
            P(f"  {ds} seed {seed} {name}: t={a[0]:.2f} s {a[1]} {a[3]}->{a[2]}: {a[4]}")
        if len(fa_alarms) > 20:
            P(f"  ... and {len(fa_alarms) - 20} more")

    # pooled RMS during faults
    P("-" * 100)
    P("fused height RMS during faults, all cases pooled (m):")
    for dataset in ("sim", "real"):
        rows = [r for r in faulted if r.dataset == dataset]
        if not rows:
            continue
        parts = []
        for name in CONTENDERS:
            rm = sm.pooled_rms((r.per[name]["f_ss"], r.per[name]["f_n"]) for r in rows)
            parts.append(f"{name} {fmt(rm, 3)} ({sm.icao_band(rm)})")
        P(f"  {dataset:<5} " + "   ".join(parts))

    # targets
    P("-" * 100)
    P("targets (simulated PX4 data; the real-log figures in brackets):")
    P(f"{'target':<58}" + "".join(f"{n:>20}" for n in CONTENDERS))

    def target_rows(dataset):
        rows = [r for r in faulted if r.dataset == dataset]
        out = {}
        for name in CONTENDERS:
            steps = [r for r in rows if case_by[r.case].target == "step" and case_by[r.case].sigma_mult >= 3.0]
            ok = sum(1 for r in steps if r.per[name]["det"].detected and r.per[name]["det"].tta_s <= 1.0)
            ramps = [r for r in rows if case_by[r.case].target == "ramp"]
            okr = sum(1 for r in ramps if r.per[name]["det"].detected
                      and r.per[name]["det"].tta_s * r.fault["magnitude"] < 3.0)
            dets = [r.per[name]["det"] for r in rows]
            iso, det = sm.isolation_rate(dets)
            out[name] = {"step": (ok, len(steps)), "ramp": (okr, len(ramps)), "iso": (iso, det)}
        return out

    sim_t = target_rows("sim")
    real_t = target_rows("real") if any(r.dataset == "real" for r in faulted) else None
    ffs = {name: ff.get(("sim all (PX4)", name)) for name in CONTENDERS}
    ffr = {name: ff.get(("real SITL log (ArduPilot)", name)) for name in CONTENDERS}

    def cell(name, key, frac_req):
        ok, n = sim_t[name][key]
        met = n > 0 and ok / n >= frac_req
        s = f"{ok}/{n}{' ok' if met else ' MISS'}"
        if real_t:
            s += f" [{real_t[name][key][0]}/{real_t[name][key][1]}]"
        return s, met

    lines = [("every step >= 3σ detected within 1 s", "step", 1.0),
             ("0.5 m/s ramp detected before its error reaches 3 m", "ramp", 1.0),
             ("faulty source identified in >= 95 % of detections", "iso", 0.95)]
    verdict = {}
    for text, key, req in lines:
        cells = [cell(n, key, req) for n in CONTENDERS]
        verdict[text] = cells[1][1]
        P(f"{text:<58}" + "".join(f"{c[0]:>20}" for c in cells))
    cells = []
    for name in CONTENDERS:
        fa, hours, rm = ffs[name]
        rate = sm.per_hour(fa, hours * 3600)
        s = f"{fmt(rate)}/h{' ok' if rate < 1.0 else ' MISS'}"
        if ffr[name]:
            s += f" [{ffr[name][0]}]"
        cells.append((s, rate < 1.0))
    verdict["< 1 false alarm per hour fault-free"] = cells[1][1]
    P(f"{'< 1 false alarm per hour fault-free':<58}" + "".join(f"{c[0]:>20}" for c in cells))
    cells = []
    for name in CONTENDERS:
        fa, hours, rm = ffs[name]
        s = f"{fmt(rm, 3)} m{' ok' if rm <= 0.85 else ' MISS'}"
        if ffr[name]:
            s += f" [{fmt(ffr[name][2], 2)}]"
        cells.append((s, rm <= 0.85))
    verdict["fault-free RMS <= 0.85 m (CAT II), PX4 rates"] = cells[1][1]
    P(f"{'fault-free RMS <= 0.85 m (CAT II), PX4 rates':<58}" + "".join(f"{c[0]:>20}" for c in cells))
    P("adaptive: " + "; ".join(f"{k}: {'MET' if v else 'MISSED'}" for k, v in verdict.items()))
    n_runs = len(free) + len(faulted)
    P(f"{n_runs} runs ({len(faulted)} with a fault) x 3 contenders in {wall:.0f} s wall, {args.workers} worker(s)")


if __name__ == "__main__":
    sys.exit(main())
