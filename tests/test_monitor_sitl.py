"""Audit on flights flown by a real ArduPilot SITL with faults injected
(../shared/tlogs/sitl): the right source, in time, cleared after the fault is
removed; no alarm on the nominal flight; on real flights either no alarm or an
explanation (inputs too slow for the time-to-alarm, no GNSS)."""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink import mavutil

from mavnav.audit import audit_file
from mavnav.config import load_config
from tests.support.paths import SHARED_TLOGS

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

TLOGS = SHARED_TLOGS
SITL = TLOGS / "sitl"


def fault_timeline(path: Path) -> list[tuple[float, str, float]]:
    """(vehicle time s, SIM_ parameter, value) from the autopilot's PARAM_VALUE
    echoes of the parameter changes that injected the faults (the logs carry
    no FAULTLOG text, whatever the inventory says)."""
    m = mavutil.mavlink_connection(str(path), robust_parsing=True)
    boot_s = None
    out = []
    while True:
        msg = m.recv_match(type=["PARAM_VALUE", "SYSTEM_TIME", "ATTITUDE"])
        if msg is None:
            return out
        if msg.get_type() != "PARAM_VALUE":
            boot_s = msg.time_boot_ms / 1000.0
            continue
        pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        if pid.startswith("SIM_") and boot_s is not None:
            out.append((boot_s, pid, float(msg.param_value)))


def onset_end(timeline):
    on = next(t for t, _, v in timeline if v != 0)
    off = next(t for t, _, v in timeline if t > on and v == 0)
    return on, off


def first_time_offset_exceeds(timeline, level):
    return next(t for t, _, v in timeline if v > level)


@pytest.fixture(scope="module")
def cfg():
    return load_config(None)


CASES = [
    # log, source, deadline rule
    ("gps_alt_step.tlog", "gnss", "tta"),
    ("rng_glitch.tlog", "rangefinder", "tta2"),
    ("gps_alt_ramp.tlog", "gnss", "ramp_4m"),
    ("baro_ramp.tlog", "baro_ins", "ramp_3m"),
]


@pytest.mark.parametrize("name, source, rule", CASES)
def test_sitl_fault_is_alarmed_in_time_and_cleared(cfg, name, source, rule):
    path = SITL / name
    tl = fault_timeline(path)
    on, off = onset_end(tl)
    r = audit_file(path, cfg)
    alarms = [a for a in r["alarms"] if a["state"] == "alarm"]
    assert alarms, "no alarm at all"
    first = alarms[0]
    assert first["source"] == source, first
    assert all(a["source"] == source for a in alarms), alarms
    if rule == "tta":
        deadline = on + cfg.monitor.time_to_alarm_s
    elif rule == "tta2":  # 30 % of readings glitched: three refusals are needed to call it erratic
        deadline = on + 2.0
    elif rule == "ramp_4m":  # SIM_GPS_ALT_OFS is an integer: the ramp moves in 1 m steps every 2 s
        deadline = first_time_offset_exceeds(tl, 3.0)
    else:
        deadline = on + 3.0 / 0.4  # 0.4 m/s: 3 m of baro error
    assert on <= first["t_s"] <= deadline, (first["t_s"], on, deadline)
    assert first["cleared_t_s"] is not None and off < first["cleared_t_s"] < off + 15.0


def test_sitl_nominal_flight_raises_no_alarm(cfg):
    r = audit_file(SITL / "copter_rangefinder_nominal.tlog", cfg)
    assert [a for a in r["alarms"] if a["state"] == "alarm"] == []
    assert r["availability"]["channels_used"]["gnss"] > 0.9
    assert r["fused_vs_autopilot_rms_m"] < 1.0


@pytest.mark.parametrize("path", sorted((TLOGS / "real").glob("*.tlog")) + sorted((TLOGS / "other").glob("*.tlog")),
                         ids=lambda p: p.name)
def test_real_flights_alarm_only_with_an_explanation(cfg, path):
    r = audit_file(path, cfg)
    if any(a["state"] == "alarm" for a in r["alarms"]):
        notes = " ".join(r["notes"])
        assert "cannot support" in notes or "no gnss samples" in notes, r["notes"]
