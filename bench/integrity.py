"""Integrity scorecard: fault families x seeds, each run scored against its truth and expected verdict.

A *family* is a named group of runs: one flight and fault rule, several
seeds, the truth, and the verdict a right monitor gives:

* a **fault family** names the faulty source: it must alarm inside the
  fault window, and no other sensor may be excluded;
* a **nominal family** (range transitions, in-flight start, GNSS wander
  within its v_acc, slow telemetry, fault-free flights) must give no alarm;
* **terrain** (a roof under the rangefinder) may blame the rangefinder and
  nothing else.

Contenders, on the same samples (every log is read once by
:class:`mavnav.ingest.TlogSource`):

* ``adaptive``: mavnav, ``monitor.mode: adaptive`` (the default);
* ``paper``: mavnav, ``monitor.mode: paper`` (the paper's Fig. 4 logic; cheap);
* ``baseline``: ``bench/autopilot_baseline.py``, a small model of what
  ArduPilot EKF3 / PX4 EKF2 do with height (one filter, 5-sigma gates, stale
  fallback, a source "fails" after 5 s of gate failures). It has no overall
  state: every output it gives counts as offered for use.

The monitor is read **only through its public outputs**: per epoch
(``EpochReport``) the vehicle time, ``height_fused_m`` and ``overall``; and
the ``AlarmEvent`` list of the run summary (source, new and previous
state). Filter noise config (``--sensor-model``): ``truth``, the scenario's
own (``Scenario.filter_sensors()``), the monitor told the simulator's noise;
or ``shipped``, mavnav's defaults (measured on real flights), as a user runs
``mavnav audit`` on a log whose sensors nobody measured. The simulator's
default baro (``u`` 0.5 m at 1 s) is 2.5 times the shipped model's 0.2 m, as
noisy at the 4 s scale as the noisiest real baro here. The SITL log always
runs on mavnav's defaults.

Scores per run (``bench/scoremetrics.py``: ``score_run``): detected (an
alarm of any source inside the fault window), time-to-alarm (first alarm
minus onset), isolated (every source alarming at that instant is the
fault's), wrong exclusions (a healthy sensor source entering alarm from the
onset on; any time on a nominal run), false alarms (alarm transitions
before the onset; on a nominal run every alarm of a source not allowed),
hazardous (the fused output more than 3 m from truth while ``overall`` is
nominal or caution), available (share of time with such a usable output).
A run is *right* when all of these are right.

Step magnitudes are in sigma of the raw sensor difference, from the
scenario's sensor model and independent of any monitor: GNSS
``hypot(v_acc, baro sigma_bb)``, rangefinder ``hypot(sigma_m, sigma_bb)``,
baro the larger of the two. Onsets are drawn from (seed, family name), so
selecting families does not move them.

Families (``--list`` prints them): the grid flights of
``px4_landing_nominal.yaml`` (60 s, PX4 rates, ground start; odd seeds an
approach to 35 m and down to 2 m, even seeds a hover at 15 m) with GNSS,
rangefinder and baro steps at 3/5/8 sigma for 10 s, GNSS and baro ramps at
0.5 m/s for 12 s, an accelerometer bias of 0.3 m/s^2, a stuck rangefinder,
and fault-free; the scenario files of issue 13 (descent from above the
rangefinder's maximum, alone, with a 12 s GNSS ramp and with one to the end; take-off and landing;
a roof; a frozen rangefinder in a descent; GNSS wander; 2-4 Hz telemetry;
in-flight start, over flat ground and over ground 3-12 m off the reference);
long fault-free flights; and faults injected into the
ArduPilot SITL log ``../shared/tlogs/sitl/copter_rangefinder_nominal.tlog``
(if present). The range families alternate the rangefinder's out-of-range
encoding by seed (odd: signal_quality 1 "invalid"; even: 0 "unknown", the
distance beyond its limits the only sign).

Usage::

    .venv/bin/python bench/integrity.py                        # default: 6 seeds, all families
    .venv/bin/python bench/integrity.py --quick                # 1 seed per family, short long flights
    .venv/bin/python bench/integrity.py --families 'gnss_*,terrain_roof' --seeds 4 --workers 1
    .venv/bin/python bench/integrity.py --contenders adaptive,baseline --json out/integrity.json
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import os
import sys
import tempfile
import time
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if __package__:  # imported as bench.integrity (the tests)
    from . import scoremetrics as sm
    from .autopilot_baseline import BaselineConfig, run_baseline
else:  # run as a script
    sys.path.insert(0, str(HERE))
    import scoremetrics as sm
    from autopilot_baseline import BaselineConfig, run_baseline

from mavnav.config import SensorsConfig, config_from_dict  # noqa: E402
from mavnav.ingest import TlogSource  # noqa: E402
from mavnav.pipeline import run  # noqa: E402
from mavnav.samples import ReferenceSet  # noqa: E402
from mavnav.sim import Fault, inject_bytes, scenario_from_dict, simulate  # noqa: E402
from mavnav.sim.simulate import read_truth_csv  # noqa: E402
from mavnav.sinks.base import Sink  # noqa: E402

CONTENDERS = ("adaptive", "paper", "baseline")
SCENARIOS = ROOT / "config" / "scenarios"
GRID_SCENARIO = SCENARIOS / "px4_landing_nominal.yaml"
REAL_LOG = (ROOT / ".." / "shared" / "tlogs" / "sitl" / "copter_rangefinder_nominal.tlog").resolve()
REAL_TRUTH = REAL_LOG.with_name("copter_rangefinder_nominal.truth.csv")
STEP_MULTS = (3.0, 5.0, 8.0)
RAMP_RATE_MPS = 0.5
STEP_DURATION_S = 10.0
RAMP_DURATION_S = 12.0
HAZARD_M = 3.0


# ---------------------------------------------------------------- families


@dataclass(frozen=True)
class Family:
    """A named group of runs: ``build(seed)`` gives one run's flight, fault and window."""

    name: str
    text: str
    expect: Optional[str]  # fault source group (sm.SOURCE_GROUPS), None: nominal
    build: Callable[[int, dict], dict]
    allowed: Tuple[str, ...] = ()  # sources that may alarm without penalty
    group: str = "sim"  # "sim", "long" (longer flights), "real" (the SITL log)
    cost: float = 1.0  # relative run time (60 s flight = 1)


def _yaml(name: str) -> dict:
    return yaml.safe_load((SCENARIOS / f"{name}.yaml").read_text())


def _u(seed: int, family: str, lo: float, hi: float, k: int = 0) -> float:
    rng = np.random.default_rng([seed, zlib.crc32(family.encode()), k])
    return float(rng.uniform(lo, hi))


def grid_flight(seed: int) -> dict:
    """The grid's flight (ground start, PX4 rates and sensors of px4_landing_nominal).

    Odd seeds: an approach (take-off, climb to 35 m at 1.5 m/s, hold 8 s,
    descend to 2 m); even seeds: take-off and hover at 15 m.
    """
    d = yaml.safe_load(GRID_SCENARIO.read_text())
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


def raw_sigmas(sensors: SensorsConfig) -> Dict[str, float]:
    """Sigma of the raw sensor differences (m): the step unit, independent of any monitor."""
    g = math.hypot(sensors.gnss.sigma_z_m, sensors.baro.sigma_bb_m)
    r = math.hypot(sensors.rangefinder.sigma_m, sensors.baro.sigma_bb_m)
    return {"gnss": g, "rangefinder": r, "baro": max(g, r), "ins": max(g, r)}


def _fault(kind: str, onset_s: float, duration_s: Optional[float], magnitude: Optional[float] = None,
           **extra) -> dict:
    f = {"kind": kind, "onset_s": round(onset_s, 3)}
    if duration_s is not None:
        f["duration_s"] = duration_s
    if magnitude is not None:
        f["magnitude"] = round(magnitude, 4)
    f.update(extra)
    return f


def _grid_fault_family(name: str, text: str, src: str, kind: str, *, mult: Optional[float] = None,
                       magnitude: Optional[float] = None, duration_s: float = STEP_DURATION_S,
                       extra: Optional[dict] = None) -> Family:
    def build(seed: int, opts: dict) -> dict:
        d = grid_flight(seed)
        on = _u(seed, name, 15.0, 30.0)
        mag = magnitude
        if mult is not None:
            sig = raw_sigmas(scenario_from_dict(d).filter_sensors())[src]
            mag = mult * sig
        f = _fault(kind, on, duration_s, mag, **(extra or {}))
        d["faults"] = [f]
        return {"scenario": d, "window": (on, on + duration_s)}
    return Family(name, text, src, build)


def _nominal_grid(seed: int, opts: dict) -> dict:
    return {"scenario": grid_flight(seed)}


def _rng_encoding(d: dict, seed: int) -> dict:
    """Even seeds: the rangefinder reports no quality (0) and out-of-range readings only by distance."""
    if seed % 2 == 0:
        rf = d.setdefault("sensors", {}).setdefault("rangefinder", {})
        rf.update(quality=0, out_of_range_quality=0)
    return d


def _descent(seed: int, opts: dict) -> dict:
    d = _rng_encoding(_yaml("px4_descent_above_rng_max"), seed)
    d["trajectory"]["heading_deg"] = round(_u(seed, "descent", 0.0, 360.0), 1)
    return {"scenario": d}


def _descent_gnss_ramp(seed: int, opts: dict) -> dict:
    d = _rng_encoding(_yaml("px4_descent_above_rng_max"), seed)
    on = _u(seed, "descent_gnss_ramp", 18.0, 28.0)
    d["faults"] = [_fault("gnss_ramp", on, RAMP_DURATION_S, RAMP_RATE_MPS)]
    return {"scenario": d, "window": (on, on + RAMP_DURATION_S)}


def _descent_gnss_ramp_to_end(seed: int, opts: dict) -> dict:
    d = _rng_encoding(_yaml("px4_descent_above_rng_max"), seed)
    on = _u(seed, "descent_gnss_ramp_to_end", 15.0, 25.0)
    d["faults"] = [_fault("gnss_ramp", on, None, RAMP_RATE_MPS)]
    return {"scenario": d, "window": (on, float(d["duration_s"]))}


def _takeoff_landing(seed: int, opts: dict) -> dict:
    d = _rng_encoding(_yaml("px4_takeoff_landing"), seed)
    d["trajectory"]["heights_m"] = [0.0, round(_u(seed, "takeoff_landing", 4.0, 12.0), 1), 0.0]
    return {"scenario": d}


def _roof(seed: int, opts: dict) -> dict:
    d = _yaml("px4_roof_terrain")
    on = _u(seed, "terrain_roof", 20.0, 30.0)
    height = round(_u(seed, "terrain_roof", 3.0, 6.0, 1), 1)
    d["terrain"] = [{"from_s": round(on, 3), "to_s": round(on + 10.0, 3), "height_m": height}]
    return {"scenario": d, "window": (on, on + 10.0)}


def _frozen_descent(seed: int, opts: dict) -> dict:
    d = _yaml("px4_rng_frozen_descent")
    on = _u(seed, "rng_frozen_descent", 10.0, 18.0)
    d["faults"] = [_fault("rng_stuck", on, 10.0)]
    return {"scenario": d, "window": (on, on + 10.0)}


def _gnss_wander(seed: int, opts: dict) -> dict:
    d = _yaml("px4_gnss_wander")
    g = d["sensors"]["gnss"]
    g["correlated_sigma_m"] = round(_u(seed, "gnss_wander", 0.3, 0.5) * g["v_acc_m"], 3)
    g["correlated_tau_s"] = round(_u(seed, "gnss_wander", 100.0, 300.0, 1), 1)
    if seed % 2 == 0:
        d["trajectory"] = {"kind": "steps", "start_height_m": 0.0, "heights_m": [20.0, 8.0, 25.0, 12.0],
                           "hold_s": 30.0, "vertical_speed_mps": 1.5}
    return {"scenario": d}


def _slow_telemetry(seed: int, opts: dict) -> dict:
    d = _yaml("ardupilot_slow_telemetry")
    r = (2.0, 3.0, 4.0)[seed % 3]
    d["rates_hz"] = {k: (0 if v == 0 else r) for k, v in d["rates_hz"].items()}
    if seed % 2 == 0:
        d["trajectory"] = {"kind": "landing", "start_height_m": 30.0, "hold_s": 8.0, "glide_slope_deg": 10.0,
                           "descent_speed_mps": 0.8, "flare_s": 6.0, "heading_deg": 300.0}
    return {"scenario": d, "note": f"{r:g} Hz"}


def _inflight(seed: int, opts: dict) -> dict:
    if seed % 2:
        d = _yaml("px4_inflight_start")
        d["trajectory"]["height_m"] = 30.0
    else:
        d = _yaml("px4_landing_nominal")  # as shipped: the monitor starts with the vehicle at 35 m
        d["faults"] = []
    return {"scenario": d}


def _inflight_terrain(seed: int, opts: dict) -> dict:
    """Joined in flight at 25 m above the reference over ground 3-12 m above
    or below it for the whole flight: the ground under the rangefinder is
    not the reference's, and nothing but the GNSS says where it is."""
    d = _yaml("px4_inflight_start")
    d["trajectory"]["height_m"] = 25.0
    size = _u(seed, "inflight_terrain", 3.0, 12.0)
    ground = round(size if _u(seed, "inflight_terrain", 0.0, 1.0, 1) < 0.5 else -size, 1)
    d["terrain"] = [{"from_s": 0.0, "to_s": float(d["duration_s"]) + 1.0, "height_m": ground}]
    return {"scenario": d, "note": f"ground {ground:+g} m"}


def _long(seed: int, opts: dict) -> dict:
    minutes = opts.get("long_minutes", 5.0)
    d = yaml.safe_load(GRID_SCENARIO.read_text())
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
    return {"scenario": d}


def _real_family(name: str, text: str, src: Optional[str], kind: Optional[str], *, mult: Optional[float] = None,
                 magnitude: Optional[float] = None, duration_s: float = STEP_DURATION_S,
                 extra: Optional[dict] = None) -> Family:
    def build(seed: int, opts: dict) -> dict:
        if kind is None:
            return {"real": True}
        on = _u(seed, name, 80.0, 200.0)
        mag = magnitude
        if mult is not None:
            mag = mult * raw_sigmas(SensorsConfig())[src]
        f = _fault(kind, on, duration_s, mag, seed=seed, **(extra or {}))
        return {"real": True, "fault": f, "window": (on, on + duration_s)}
    return Family(name, text, src, build, group="real", cost=2.0)


def families() -> List[Family]:
    out: List[Family] = []
    for kind, src, short, extra in (("gnss_step", "gnss", "gnss", None),
                                    ("rng_spikes", "rangefinder", "rng", {"probability": 1.0}),
                                    ("baro_step", "baro", "baro", None)):
        for m in STEP_MULTS:
            out.append(_grid_fault_family(
                f"{short}_step{m:g}", f"{short} step {m:g} sigma for {STEP_DURATION_S:g} s on the grid flights",
                src, kind, mult=m, extra=extra))
    out.append(_grid_fault_family("gnss_ramp", f"GNSS ramp {RAMP_RATE_MPS:g} m/s for {RAMP_DURATION_S:g} s "
                                  "on the grid flights", "gnss", "gnss_ramp", magnitude=RAMP_RATE_MPS,
                                  duration_s=RAMP_DURATION_S))
    out.append(_grid_fault_family("baro_ramp", f"baro ramp {RAMP_RATE_MPS:g} m/s for {RAMP_DURATION_S:g} s "
                                  "on the grid flights", "baro", "baro_ramp", magnitude=RAMP_RATE_MPS,
                                  duration_s=RAMP_DURATION_S))
    out.append(_grid_fault_family("accel_bias", "accelerometer bias step 0.3 m/s² for 10 s on the grid flights",
                                  "ins", "accel_bias_step", magnitude=0.3))
    out.append(_grid_fault_family("rng_stuck", "rangefinder stuck (last reading held) for 10 s on the grid "
                                  "flights", "rangefinder", "rng_stuck"))
    out.append(Family("fault_free", "the grid flights without a fault", None, _nominal_grid))
    out += [
        Family("descent_above_max", "descent from 55 m, above the rangefinder's 40 m max, to touchdown "
               "(px4_descent_above_rng_max)", None, _descent),
        Family("descent_gnss_ramp", "the same descent with a GNSS ramp 0.5 m/s for 12 s", "gnss",
               _descent_gnss_ramp),
        Family("descent_gnss_ramp_to_end", "the same descent with a GNSS ramp 0.5 m/s from 15-25 s to the end "
               "(17-22 m)", "gnss", _descent_gnss_ramp_to_end),
        Family("takeoff_landing", "take-off to 4-12 m and landing through the rangefinder's 0.2 m min "
               "(px4_takeoff_landing)", None, _takeoff_landing),
        Family("terrain_roof", "hover at 12 m over a 3-6 m roof for 10 s (px4_roof_terrain): only the "
               "rangefinder may be blamed", None, _roof, allowed=("rangefinder",)),
        Family("rng_frozen_descent", "rangefinder frozen for 10 s while descending from 25 m "
               "(px4_rng_frozen_descent)", "rangefinder", _frozen_descent),
        Family("gnss_wander", "180 s; GNSS Gauss-Markov wander 0.3-0.5 x v_acc, tau 100-300 s, inside "
               "its v_acc (px4_gnss_wander)", None, _gnss_wander, cost=3.0),
        Family("slow_telemetry", "every stream at 2, 3 or 4 Hz (ardupilot_slow_telemetry): degraded or "
               "unavailable, never a sensor", None, _slow_telemetry, cost=0.3),
        Family("inflight_start", "the monitor connects with the vehicle at 30-35 m (px4_inflight_start, "
               "px4_landing_nominal)", None, _inflight),
        Family("inflight_terrain", "the monitor connects with the vehicle at 25 m over ground 3-12 m above or "
               "below the reference (px4_inflight_start with terrain)", None, _inflight_terrain),
        Family("long_fault_free", "fault-free flights of --long-minutes (hover, height steps)", None, _long,
               group="long", cost=5.0),
    ]
    out += [
        _real_family("real_fault_free", "the ArduPilot SITL log as recorded", None, None),
        _real_family("real_gnss_step5", "SITL log + GNSS step 5 sigma (mavnav default noise) for 10 s",
                     "gnss", "gnss_step", mult=5.0),
        _real_family("real_baro_step5", "SITL log + baro step 5 sigma for 10 s", "baro", "baro_step", mult=5.0),
        _real_family("real_rng_step5", "SITL log + rangefinder step 5 sigma for 10 s", "rangefinder",
                     "rng_spikes", mult=5.0, extra={"probability": 1.0}),
        _real_family("real_gnss_ramp", "SITL log + GNSS ramp 0.5 m/s for 12 s", "gnss", "gnss_ramp",
                     magnitude=RAMP_RATE_MPS, duration_s=RAMP_DURATION_S),
        _real_family("real_rng_stuck", "SITL log + rangefinder stuck for 10 s", "rangefinder", "rng_stuck"),
    ]
    return out


FAMILIES: Dict[str, Family] = {f.name: f for f in families()}


def select(patterns: Optional[str]) -> List[Family]:
    """Families whose names match any comma-separated glob (all if None)."""
    if not patterns:
        return list(FAMILIES.values())
    pats = [p.strip() for p in patterns.split(",") if p.strip()]
    bad = [p for p in pats if not any(fnmatch.fnmatchcase(n, p) for n in FAMILIES)]
    if bad:
        raise SystemExit(f"--families: no family matches {', '.join(bad)} (see --list)")
    return [f for n, f in FAMILIES.items() if any(fnmatch.fnmatchcase(n, p) for p in pats)]


# ---------------------------------------------------------------- running the contenders


class _Collect(Sink):
    """Per epoch, the public outputs: vehicle time, fused height, overall state."""

    name = "collect"

    def __init__(self) -> None:
        self.t: List[float] = []
        self.h: List[float] = []
        self.overall: List[str] = []
        self.pl: List[float] = []

    def epoch(self, r) -> None:
        self.t.append(r.t_us * 1e-6)
        self.h.append(r.height_fused_m)
        self.overall.append(r.overall)
        self.pl.append(r.vpl_m)


def run_contenders(samples: list, sensors: SensorsConfig, names: Sequence[str], bcfg: BaselineConfig) -> Dict[str, dict]:
    out = {}
    for name in names:
        if name == "baseline":
            b = run_baseline(samples, sensors, bcfg)
            out[name] = {"t": b.t_s, "h": b.height_m, "overall": None, "alarms": list(b.alarms)}
            continue
        cfg = config_from_dict({"sensors": sensors.model_dump(), "monitor": {"mode": name}})
        sink = _Collect()
        summary = run(samples, cfg, [sink])
        out[name] = {"t": np.asarray(sink.t), "h": np.asarray(sink.h, dtype=float), "overall": sink.overall,
                     "pl": np.asarray(sink.pl, dtype=float), "alarms": list(summary.alarms)}
    return out


def ingest(data: bytes) -> list:
    fd, path = tempfile.mkstemp(suffix=".tlog", prefix="mavnav-score-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        return list(TlogSource(path, config_from_dict({}).ingest))
    finally:
        os.unlink(path)


def _truth_real(samples: list) -> Tuple[np.ndarray, np.ndarray]:
    tr = read_truth_csv(REAL_TRUTH)
    ref = next((s.alt_ref_msl_m for s in samples if isinstance(s, ReferenceSet) and s.alt_ref_msl_m is not None), None)
    if ref is None:
        raise RuntimeError("the real log carries no home altitude")
    return np.asarray(tr["t_s"], dtype=float), np.asarray(tr["true_alt_msl_m"], dtype=float) - ref


@dataclass
class RunResult:
    family: str
    seed: int
    fault: Optional[dict]
    window: Optional[Tuple[float, float]]
    note: str
    span_s: float
    scores: Dict[str, dict] = field(default_factory=dict)  # contender -> RunScore as a dict
    alarms: Dict[str, list] = field(default_factory=dict)  # contender -> [(t_s, source, previous, state, reason)]
    wall_s: float = 0.0


def job(spec: dict) -> RunResult:
    t_wall = time.perf_counter()
    fam = FAMILIES[spec["family"]]
    seed = spec["seed"]
    b = fam.build(seed, spec)
    if b.get("real"):
        data = REAL_LOG.read_bytes()
        fault = b.get("fault")
        if fault is not None:
            data, _ = inject_bytes(data, [Fault.model_validate(fault)])
        samples = ingest(data)
        sensors = SensorsConfig()
        t_truth, h_truth = _truth_real(samples)
    else:
        scn = scenario_from_dict(b["scenario"])
        fault = b["scenario"]["faults"][0] if b["scenario"].get("faults") else None
        res = simulate(scn, seed=seed)
        samples = ingest(res.tlog)
        sensors = scn.filter_sensors() if spec.get("sensor_model", "truth") == "truth" else SensorsConfig()
        t_truth = np.asarray(res.truth["t_s"], dtype=float)
        h_truth = np.asarray(res.truth["true_height_ref_m"], dtype=float)
    outs = run_contenders(samples, sensors, spec["contenders"], BaselineConfig(fail_s=spec["baseline_fail_s"]))
    ts = [s.t_us for s in samples if getattr(s, "t_us", None) is not None]
    r = RunResult(fam.name, seed, fault, b.get("window"), b.get("note", ""),
                  (max(ts) - min(ts)) * 1e-6 if ts else 0.0)
    expected = sm.SOURCE_GROUPS[fam.expect] if fam.expect else ()
    for name, o in outs.items():
        sc = sm.score_run(o["alarms"], o["t"], o["h"], o["overall"], t_truth, h_truth, window=b.get("window"),
                          expected=expected, allowed=fam.allowed, hazard_m=HAZARD_M)
        d = asdict(sc)
        d["right"], d["hazardous"] = sc.right, sc.hazardous
        d["misleading_s"], d["usable_s"] = (sm.misleading(o["t"], o["h"], o["pl"], o["overall"], t_truth, h_truth)
                                            if o.get("pl") is not None else (math.nan, math.nan))
        r.scores[name] = d
        r.alarms[name] = [(round(a.t_s, 3), a.source, a.previous, a.state, a.reason)
                          for a in sm.alarm_onsets(o["alarms"])]
    r.wall_s = time.perf_counter() - t_wall
    return r


def run_jobs(specs: List[dict], workers: int) -> List[RunResult]:
    if workers <= 1:
        return [job(s) for s in specs]
    import multiprocessing as mp

    specs = sorted(specs, key=lambda s: -FAMILIES[s["family"]].cost)  # long runs first
    with mp.get_context("fork").Pool(workers) as pool:
        return list(pool.imap_unordered(job, specs, chunksize=1))


# ---------------------------------------------------------------- aggregation and report


def fmt(v, nd: int = 2) -> str:
    if v is None or (isinstance(v, float) and not (v == v)):
        return "-"
    return f"{v:.{nd}f}"


def aggregate(rows: List[RunResult], name: str, fam: Family) -> dict:
    sc = [r.scores[name] for r in rows]
    n = len(sc)
    ttas = [s["tta_s"] for s in sc if s["detected"]]
    med = sm.tta_stats(ttas)[0]
    alarmed: Dict[str, int] = {}
    for s in sc:
        for src in s["alarmed"]:
            alarmed[src] = alarmed.get(src, 0) + 1
    avail = [s["available_frac"] for s in sc if s["available_frac"] == s["available_frac"]]
    caution = [s["caution_frac"] for s in sc if s.get("caution_frac", math.nan) == s.get("caution_frac", math.nan)]
    return {
        "runs": n,
        "fault": fam.expect is not None,
        "detected": sum(s["detected"] for s in sc),
        "tta_median_s": med,
        "tta_within_1s": sum(1 for s in sc if s["detected"] and s["tta_s"] <= 1.0),
        "isolated": sum(1 for s in sc if s["detected"] and s["isolated"]),
        "wrong_exclusion_runs": sum(1 for s in sc if s["wrong_exclusions"]),
        "hazardous_runs": sum(1 for s in sc if s["hazardous"]),
        "hazardous_s": float(sum(s["hazardous_s"] for s in sc)),
        "max_usable_error_m": float(max((s["max_usable_error_m"] for s in sc
                                         if s["max_usable_error_m"] == s["max_usable_error_m"]), default=math.nan)),
        "false_alarms": sum(s["false_alarms"] for s in sc),
        "available_pct": 100.0 * float(np.mean(avail)) if avail else math.nan,
        "caution_pct": 100.0 * float(np.mean(caution)) if caution else math.nan,
        "right": sum(1 for s in sc if s["right"]),
        "misleading_s": float(sum(s.get("misleading_s", 0.0) for s in sc if s.get("misleading_s") == s.get("misleading_s"))),
        "usable_s": float(sum(s.get("usable_s", 0.0) for s in sc if s.get("usable_s") == s.get("usable_s"))),
        "alarmed_runs_by_source": dict(sorted(alarmed.items())),
    }


def family_table(fam: Family, rows: List[RunResult], names: Sequence[str]) -> Tuple[List[str], Dict[str, dict]]:
    exp = "no alarm" if fam.expect is None else f"alarm on {'/'.join(sm.SOURCE_GROUPS[fam.expect])}"
    if fam.allowed:
        exp += f" ({', '.join(fam.allowed)} may alarm)"
    notes = sorted({r.note for r in rows if r.note})
    lines = [f"### {fam.name}", "", f"{fam.text}. Expected: {exp}. Seeds {', '.join(str(r.seed) for r in sorted(rows, key=lambda r: r.seed))}"
             + (f" ({', '.join(notes)})" if notes else "") + ".", ""]
    lines.append("| contender | runs | detected | TTA med s | TTA ≤ 1 s | isolated | wrong excl | hazardous (s) "
                 "| false alarms | avail % | caution % | right | alarmed (runs) |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    aggs = {}
    for name in names:
        a = aggregate(rows, name, fam)
        aggs[name] = a
        n = a["runs"]
        if a["fault"]:
            det = f"{a['detected']}/{n}"
            tta, t1, iso = fmt(a["tta_median_s"]), f"{a['tta_within_1s']}/{n}", f"{a['isolated']}/{a['detected']}"
        else:
            det, tta, t1, iso = "-", "-", "-", "-"
        al = ", ".join(f"{k} {v}" for k, v in a["alarmed_runs_by_source"].items()) or "none"
        lines.append(f"| {name} | {n} | {det} | {tta} | {t1} | {iso} | {a['wrong_exclusion_runs']} | "
                     f"{a['hazardous_runs']} ({fmt(a['hazardous_s'], 1)}) | {a['false_alarms']} | "
                     f"{fmt(a['available_pct'], 0)} | {fmt(a['caution_pct'], 1)} | **{a['right']}/{n}** | {al} |")
    return lines, aggs


def totals_table(all_aggs: Dict[str, Dict[str, dict]], names: Sequence[str]) -> List[str]:
    lines = ["### totals", "", "Runs right per family (right/runs), then per contender over every family.", ""]
    lines.append("| family | " + " | ".join(names) + " |")
    lines.append("|---|" + "---|" * len(names))
    for fam, aggs in all_aggs.items():
        lines.append(f"| {fam} | " + " | ".join(f"{aggs[n]['right']}/{aggs[n]['runs']}" for n in names) + " |")
    lines.append("")
    lines.append("| contender | families all right | runs right | fault runs detected | isolated / detected "
                 "| TTA ≤ 1 s | wrong-exclusion runs | hazardous runs (s) | false alarms "
                 "| error beyond the protection level (s of usable s) |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    for n in names:
        A = [aggs[n] for aggs in all_aggs.values()]
        fa = [a for a in A if a["fault"]]
        lines.append(
            f"| {n} | {sum(1 for a in A if a['right'] == a['runs'])}/{len(A)} | "
            f"{sum(a['right'] for a in A)}/{sum(a['runs'] for a in A)} | "
            f"{sum(a['detected'] for a in fa)}/{sum(a['runs'] for a in fa)} | "
            f"{sum(a['isolated'] for a in fa)}/{sum(a['detected'] for a in fa)} | "
            f"{sum(a['tta_within_1s'] for a in fa)}/{sum(a['runs'] for a in fa)} | "
            f"{sum(a['wrong_exclusion_runs'] for a in A)} | "
            f"{sum(a['hazardous_runs'] for a in A)} ({fmt(sum(a['hazardous_s'] for a in A), 1)}) | "
            f"{sum(a['false_alarms'] for a in A)} | "
            f"{fmt(sum(a['misleading_s'] for a in A), 1)} of {fmt(sum(a['usable_s'] for a in A), 0)} |")
    return lines


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--families", default=None,
                    help="comma-separated globs of family names (default: all; --list shows them)")
    ap.add_argument("--list", action="store_true", help="list the families and exit")
    ap.add_argument("--seeds", type=int, default=6, help="seeds per family (default 6; long and real: a third)")
    ap.add_argument("--long-minutes", type=float, default=5.0, help="minutes per long fault-free flight (default 5)")
    ap.add_argument("--contenders", default=",".join(CONTENDERS),
                    help=f"comma-separated, from {', '.join(CONTENDERS)} (default: all three)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--sensor-model", choices=("truth", "shipped"), default="truth",
                    help="the monitor's noise model on simulated flights: the scenario's own (truth, default) "
                         "or mavnav's shipped defaults, as a user runs it (shipped)")
    ap.add_argument("--baseline-fail-s", type=float, default=5.0,
                    help="baseline: gate failures this long = source failure (EKF3/EKF2: 5 s)")
    ap.add_argument("--quick", action="store_true", help="smoke run: 1 seed per family, 1-minute long flights")
    ap.add_argument("--json", dest="json_path", default=None, help="write every run and every aggregate here")
    args = ap.parse_args(argv)
    if args.list:
        for f in FAMILIES.values():
            exp = "nominal" if f.expect is None else f.expect
            print(f"{f.name:<20} {f.group:<5} {exp:<12} {f.text}")
        return 0
    names = [n.strip() for n in args.contenders.split(",") if n.strip()]
    bad = [n for n in names if n not in CONTENDERS]
    if bad or not names:
        raise SystemExit(f"--contenders: unknown {', '.join(bad) or '(none)'}; choose from {', '.join(CONTENDERS)}")
    if args.quick:
        args.seeds, args.long_minutes = 1, 1.0
    fams = select(args.families)
    if not REAL_LOG.exists() and any(f.group == "real" for f in fams):
        print(f"note: {REAL_LOG} not found: the real-log families are skipped")
        fams = [f for f in fams if f.group != "real"]
    specs = []
    for f in fams:
        n = args.seeds if f.group == "sim" else max(1, args.seeds // 3)
        for seed in range(1, n + 1):
            specs.append({"family": f.name, "seed": seed, "contenders": names, "long_minutes": args.long_minutes,
                          "baseline_fail_s": args.baseline_fail_s, "sensor_model": args.sensor_model})
    t0 = time.perf_counter()
    results = run_jobs(specs, args.workers)
    wall = time.perf_counter() - t0

    P = print
    P(f"# mavnav integrity scorecard by family ({len(specs)} runs x {len(names)} contenders, "
      f"{wall:.0f} s wall, {args.workers} worker(s))")
    P("")
    P(f"Contenders: {', '.join(names)}. Read through public outputs only (EpochReport overall, "
      f"height_fused_m; AlarmEvent). Hazardous: fused output > {HAZARD_M:g} m from truth while overall is "
      "nominal or caution (baseline: always offered). Step sigma: raw sensor difference from the sensor model. "
      f"The monitor's noise model on simulated flights: {args.sensor_model} ('truth': the scenario's own; "
      "'shipped': mavnav's defaults).")
    P("")
    all_aggs: Dict[str, Dict[str, dict]] = {}
    for f in fams:
        rows = [r for r in results if r.family == f.name]
        lines, aggs = family_table(f, rows, names)
        all_aggs[f.name] = aggs
        P("\n".join(lines))
        P("")
    P("\n".join(totals_table(all_aggs, names)))
    if args.json_path:
        payload = {
            "args": {k: v for k, v in vars(args).items()},
            "wall_s": wall,
            "families": {f.name: {"text": f.text, "expect": f.expect, "allowed": list(f.allowed), "group": f.group,
                                  "contenders": all_aggs[f.name]} for f in fams},
            "runs": [asdict(r) for r in sorted(results, key=lambda r: (r.family, r.seed))],
        }
        Path(args.json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json_path).write_text(json.dumps(payload, indent=1, default=_json_default) + "\n")
        P(f"\nJSON: {args.json_path}")
    return 0


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


if __name__ == "__main__":
    sys.exit(main())
