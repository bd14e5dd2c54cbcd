"""A home that moves mid-run (a new home set at arming, at another altitude): the
reported heights follow it, the filters keep their frame and see no step.

Recorded streams built from real pymavlink messages (tests.support.flightlog.FlightLog),
replayed through the same pipeline as ``run``; the console, the CSV and the
MAVLink output say the move."""

from __future__ import annotations

import csv
import math

import pytest
from click.testing import CliRunner

from mavnav.cli import main
from mavnav.config import config_from_dict
from mavnav.ingest import TlogSource
from mavnav.pipeline import run
from mavnav.samples import AutopilotHeight, ReferenceMoved
from mavnav.sinks.base import Sink
from tests.support.flightlog import FlightLog, collect, of

GROUND_MSL_M = 480.0  # where the vehicle stands, and takes off from
STALE_HOME_MSL_M = 478.5  # the home set at the first GNSS fix, before arming
ARM_S = 15.0  # the new home is set at arming, on the ground
CLIMB_S, UP_M = 20.0, 10.0  # then it climbs to 10 m over 5 s and hovers


def height(t: float) -> float:
    if t < CLIMB_S:
        return 0.0
    x = min(1.0, (t - CLIMB_S) / 5.0)  # a smooth climb: the IMU can carry its acceleration
    return UP_M * 0.5 * (1.0 - math.cos(math.pi * x)) + 0.1 * math.sin(1.3 * t)


def arming_flight(path, *, home_position=True, seconds=40.0):
    """On the ground at 480 m under a stale home at 478.5 m until arming at 15 s (home 480 m), then up 10 m.
    GLOBAL_POSITION_INT says alt and the height above the home of the moment; HOME_POSITION (when
    streamed) every 2 s, as autopilots re-send it."""
    f = FlightLog(path)
    k = 0
    while k * 0.25 < seconds:
        t = k * 0.25
        f.fly(t, t + 0.25, height_fn=height, ground_msl_m=GROUND_MSL_M, range_hz=0, imu_follows_height=True)
        t1 = t + 0.24
        home = STALE_HOME_MSL_M if t1 < ARM_S else GROUND_MSL_M
        alt = GROUND_MSL_M + height(t1)
        f.gpi(t1, alt, rel_m=alt - home)
        if home_position and k % 8 == 0 or home_position and abs(t - ARM_S) < 1e-9:
            f.home(t1, home)
        k += 1
    return f.close()


class Rows(Sink):
    name = "rows"

    def __init__(self):
        self.reports, self.alarms, self.samples = [], [], []

    def sample(self, s):
        self.samples.append(s)

    def epoch(self, r):
        self.reports.append(r)

    def alarm(self, ev):
        self.alarms.append(ev)


def _run(path, **ingest):
    cfg = config_from_dict({"ingest": ingest})
    rows = Rows()
    summary = run(TlogSource(path, cfg.ingest), cfg, [rows])
    assert not summary.sink_failures
    return rows


def _at(rows, t0_s, t1_s):
    """Fused heights of the epochs between t0_s and t1_s of log time (vehicle time - 5 s)."""
    return [r.height_fused_m for r in rows.reports
            if t0_s <= r.t_s - 5.0 < t1_s and r.height_fused_m == r.height_fused_m]


@pytest.mark.slow
def test_a_new_home_at_arming_moves_the_reported_heights_not_the_filters(tmp_path):
    path = arming_flight(tmp_path / "arming.tlog")
    rows = _run(path)
    moves = of(rows.samples, ReferenceMoved)
    # one move, when the new home came (HOME_POSITION re-sent every 2 s moves nothing)
    assert len(moves) == 1
    mv = moves[0]
    assert (mv.origin, mv.alt_ref_msl_m) == ("home", pytest.approx(GROUND_MSL_M))
    assert mv.shift_m == pytest.approx(GROUND_MSL_M - STALE_HOME_MSL_M) == mv.offset_m
    assert mv.t_us * 1e-6 - 5.0 == pytest.approx(ARM_S + 0.24, abs=0.02)  # vehicle time of the message
    # heights above the stale home before arming, above the new one after: 0 on the ground, 10 m up
    before, ground, up = _at(rows, 5, ARM_S), _at(rows, ARM_S + 1, CLIMB_S), _at(rows, 27, 40)
    assert before and ground and up
    assert all(abs(h - 1.5) < 0.5 for h in before)
    assert all(abs(h) < 0.5 for h in ground)
    assert all(abs(h - UP_M) < 0.6 for h in up)
    # the autopilot's height is above the new home too: it agrees with the fused one
    late = [r for r in rows.reports if r.t_s - 5.0 > 27 and r.height_fused_m == r.height_fused_m]
    assert all(abs(r.autopilot_height_ref_m - r.height_fused_m) < 0.6 for r in late)
    assert all(abs(a.height_ref_m - UP_M) < 0.2 for a in of(rows.samples, AutopilotHeight) if a.t_us * 1e-6 > 32)
    # the filters saw no step: no source doubted
    assert not [a for a in rows.alarms if a.source != "input" and a.state in ("caution", "alarm")]

    # the same run without following the home: the filters computed exactly the same, the
    # reports differ by the move from the moment it came
    still = _run(path, follow_home=False)
    assert not of(still.samples, ReferenceMoved)
    assert len(still.reports) == len(rows.reports)
    for a, b in zip(rows.reports, still.reports):
        assert a.t_us == b.t_us and a.sources == b.sources and a.sigma_fused_m == b.sigma_fused_m
        d = mv.offset_m if a.t_us >= mv.t_us else 0.0
        assert a.height_fused_m == pytest.approx(b.height_fused_m - d, abs=1e-9, nan_ok=True)
        for ca, cb in zip(a.channels, b.channels):
            assert ca.height_ref_m == pytest.approx(cb.height_ref_m - d, abs=1e-9, nan_ok=True)
    assert all(abs(h - UP_M - 1.5) < 0.6 for h in _at(still, 27, 40))  # the stale home's heights


def test_without_home_position_the_autopilots_own_home_moves_it(tmp_path):
    """ArduPilot-like link with no HOME_POSITION stream: GLOBAL_POSITION_INT's alt - relative_alt
    changes at arming; followed once three messages in a row agree."""
    path = arming_flight(tmp_path / "gpi.tlog", home_position=False)
    items, _ = collect(path)
    moves = of(items, ReferenceMoved)
    assert len(moves) == 1 and moves[0].origin == "autopilot_home"
    assert moves[0].offset_m == pytest.approx(1.5, abs=0.002)
    assert moves[0].t_us * 1e-6 - 5.0 == pytest.approx(ARM_S + 0.24 + 2 * 0.25, abs=0.02)  # the third message
    rows = _run(path)
    assert all(abs(h) < 0.5 for h in _at(rows, ARM_S + 2, CLIMB_S))
    assert all(abs(h - UP_M) < 0.6 for h in _at(rows, 27, 40))


def test_a_re_sent_or_rounded_home_is_no_move(tmp_path):
    f = FlightLog(tmp_path / "same.tlog")
    for k in range(80):
        t = k * 0.25
        f.fly(t, t + 0.25, ground_msl_m=GROUND_MSL_M, range_hz=0)
        f.gpi(t + 0.24, GROUND_MSL_M + (0.003 if k % 2 else 0.0), rel_m=0.0)  # mm jitter of alt - relative_alt
        if k % 4 == 0:
            f.home(t + 0.24, GROUND_MSL_M + (0.004 if k % 8 else 0.0))
    items, st = collect(f.close())
    assert not of(items, ReferenceMoved) and st.reference_moves == 0


def test_the_move_is_said_on_the_console_and_in_the_csv(tmp_path):
    path = arming_flight(tmp_path / "arming.tlog", seconds=30.0)
    out = tmp_path / "est.csv"
    res = CliRunner().invoke(main, ["replay", str(path), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    said = "HOME MOVED +1.50 m to 480.00 m MSL (HOME_POSITION): heights are now above the new home"
    assert f"] input       {said}" in res.output
    rows = list(csv.DictReader(out.open(encoding="utf-8")))
    ev = [r for r in rows if r["event"].startswith("home moved")]
    assert len(ev) == 1 and ev[0]["event"] == f"home moved: {said}" and ev[0]["height_fused_m"] == ""
    i = rows.index(ev[0])
    after = [float(r["height_fused_m"]) for r in rows[i + 1:] if not r["event"] and r["height_fused_m"] != "nan"]
    before = [float(r["height_fused_m"]) for r in rows[:i] if not r["event"] and r["height_fused_m"] != "nan"]
    assert abs(before[-1] - 1.5) < 0.5 and abs(after[0]) < 0.5
