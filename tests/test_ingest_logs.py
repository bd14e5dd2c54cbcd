"""Every shared tlog goes through TlogSource, and its sample counts match an
independent count made here with pymavlink's own parser and the documented rules."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import pytest
from pymavlink import mavutil

from mavnav.config import IngestConfig
from mavnav.ingest import TlogSource, expand_tlog_paths
from mavnav.samples import Rejected
from tests.support.paths import SHARED_TLOGS

pytestmark = [pytest.mark.realdata, pytest.mark.slow]

TLOGS = SHARED_TLOGS
LOGS = expand_tlog_paths(TLOGS) if TLOGS.is_dir() else []

# Stuck detection depends on the barometer history; it has its own test.
CONFIG = IngestConfig(rangefinder_stuck_s=1e9)
IMU_RANK = ["HIGHRES_IMU", "RAW_IMU", "SCALED_IMU", "SCALED_IMU2", "SCALED_IMU3"]
REBOOT_JUMP_MS = 2000


def independent_counts(path: Path) -> dict:
    """Valid measurements per kind, by pymavlink, with the rules of the normaliser."""
    m = mavutil.mavlink_connection(str(path), robust_parsing=True)
    sysid = ap_comp = autopilot = mav_type = None
    msgs = []
    while True:
        msg = m.recv_msg()
        if msg is None:
            break
        t = msg.get_type()
        if t == "BAD_DATA":
            continue
        if sysid is None:
            if t == "HEARTBEAT" and msg.autopilot != 8 and msg.type != 6:
                sysid, ap_comp, autopilot = msg.get_srcSystem(), msg.get_srcComponent(), msg.autopilot
                mav_type = msg.type
            else:
                msgs.append(msg)  # held until the vehicle is known, as the source does
                continue
        msgs.append(msg)
    msgs = [x for x in msgs if x.get_srcSystem() == sysid]
    present = {x.get_type() for x in msgs}
    imu_types = [n for n in IMU_RANK if n in present and (n != "RAW_IMU" or autopilot == 3)]
    imu_type = imu_types[0] if imu_types else None
    range_type = "DISTANCE_SENSOR" if any(
        x.get_type() == "DISTANCE_SENSOR" and x.orientation == 25 for x in msgs) else (
        "RANGEFINDER" if "RANGEFINDER" in present else None)

    counts = Counter()
    last = {}
    boot = 0
    max_boot_ms = None

    def accept(kind, t):
        key = (kind, boot)
        if key in last and t <= last[key]:
            return
        last[key] = t
        counts[kind] += 1

    for x in msgs:
        t = x.get_type()
        tb = getattr(x, "time_boot_ms", None)
        if tb is not None and x.get_srcComponent() == ap_comp:
            if max_boot_ms is not None and tb < max_boot_ms - REBOOT_JUMP_MS:
                boot += 1
                max_boot_ms = tb
            max_boot_ms = tb if max_boot_ms is None else max(max_boot_ms, tb)
        if t == imu_type:
            acc = (x.xacc, x.yacc, x.zacc)
            if all(math.isfinite(a) for a in acc):
                accept("imu", x.time_usec if hasattr(x, "time_usec") else x.time_boot_ms * 1000)
        elif t == "SCALED_PRESSURE":
            if math.isfinite(x.press_abs) and x.press_abs > 0:
                accept("baro", x.time_boot_ms)
        elif t == "GPS_RAW_INT":
            if x.fix_type >= 3:
                accept("gnss", x.time_usec)
        elif t == "DISTANCE_SENSOR" and range_type == t:
            if x.orientation == 25 and x.signal_quality != 1:
                if x.min_distance <= x.current_distance <= (x.max_distance or 10000):
                    accept("range", x.time_boot_ms)
        elif t == "GLOBAL_POSITION_INT":
            accept("autopilot", x.time_boot_ms)
            if x.lat != 0 or x.lon != 0:  # with a position: an altitude MSL
                accept("autopilot_msl", x.time_boot_ms)
    if mav_type in (11, 12):  # a surface vessel or a submarine: no height samples (vehicle_class)
        for kind in ("baro", "gnss", "range"):
            counts[kind] = 0
    return counts, imu_type, range_type


@pytest.mark.skipif(not LOGS, reason="shared/tlogs not beside the checkout")
@pytest.mark.parametrize("path", LOGS, ids=lambda p: p.name)
def test_log_counts_match_pymavlink(path):
    src = TlogSource(path, CONFIG)
    got = Counter()
    refused = Counter()
    for s in src:
        if isinstance(s, Rejected):
            if s.kind in ("no_attitude", "tilt"):
                refused[s.detail.split()[0].rstrip(":")] += 1
        else:
            got[type(s).__name__] += 1
    want, imu_type, range_type = independent_counts(path)
    st = src.stats
    assert st.imu_source == imu_type
    assert st.range_source == range_type
    # every valid IMU / rangefinder message is a sample or an explicit refusal
    assert got["SpecificForceUp"] + refused[imu_type] == want["imu"]
    assert got["RangeHeight"] + refused[range_type] == want["range"]
    assert got["BaroHeight"] == want["baro"]
    assert got["GnssHeight"] == want["gnss"]
    # above the GNSS reference only those with a position (ArduPilot sends alt 0 without one);
    # above the autopilot's own home all of them
    ap_kind = "autopilot_msl" if st.autopilot_reference == "gnss_reference" else "autopilot"
    assert got["AutopilotHeight"] == want[ap_kind]
    # refusals stay the exception on real logs
    assert refused[imu_type] <= 0.05 * max(1, want["imu"])
    for kind, n in st.samples.items():
        assert n == got[{"imu": "SpecificForceUp", "baro": "BaroHeight", "gnss": "GnssHeight",
                         "range": "RangeHeight", "autopilot": "AutopilotHeight"}[kind]]
