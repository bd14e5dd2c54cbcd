"""Vehicles height integrity does not apply to (a submarine, a surface vessel):
said once, their height samples dropped, never an alarm from a model that does
not fit. Real pymavlink encoding: the same simulated tlog with the HEARTBEAT's
type rewritten, against the unmodified one as the control."""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from mavnav.audit import audit_file
from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.ingest.vehicle_class import not_applicable_reason
from mavnav.samples import BaroHeight, GnssHeight, Notice, RangeHeight
from tests.support.paths import SHARED

REPO = Path(__file__).resolve().parents[1]
SIM_TLOG = REPO / "sitl_logs" / "ardupilot_rng_dropout.tlog"
ARDUSUB = SHARED / "tlogs" / "real" / "ardusub_rov_sonar_2023.tlog"


def _retyped(src: Path, dst: Path, mav_type: int) -> Path:
    """``src`` with every HEARTBEAT of the vehicle re-encoded with ``type = mav_type``."""
    m = mavutil.mavlink_connection(str(src))
    out = bytearray()
    while True:
        msg = m.recv_msg()
        if msg is None:
            break
        stamp = int(getattr(msg, "_timestamp", 0) * 1e6).to_bytes(8, "big")
        if msg.get_type() == "HEARTBEAT" and msg.autopilot != 8 and msg.type != 6:
            enc = mavlink2.MAVLink(None, srcSystem=msg.get_srcSystem(), srcComponent=msg.get_srcComponent())
            enc.seq = msg.get_seq()
            hb = enc.heartbeat_encode(mav_type, msg.autopilot, msg.base_mode, msg.custom_mode,
                                      msg.system_status, msg.mavlink_version)
            out += stamp + hb.pack(enc)
        else:
            out += stamp + msg.get_msgbuf()
    dst.write_bytes(bytes(out))
    return dst


def _kinds(path: Path):
    src = open_log(path, config_from_dict({}).ingest)
    items = list(src)
    return items, src.stats


def test_table():
    assert "submarine" in not_applicable_reason(mav_type=12)
    assert "surface vessel" in not_applicable_reason(mav_type=11)
    assert not_applicable_reason(mav_type=2) is None  # a quadrotor
    assert not_applicable_reason(kind="sub") == not_applicable_reason(mav_type=12)
    assert not_applicable_reason(kind="copter") is None


@pytest.mark.parametrize("mav_type,word", [pytest.param(12, "submarine", marks=pytest.mark.slow), (11, "surface vessel")])
def test_water_vehicle_drops_height_samples(tmp_path, mav_type, word):
    control, cst = _kinds(SIM_TLOG)
    n_height = sum(isinstance(s, (BaroHeight, GnssHeight, RangeHeight)) for s in control)
    assert n_height > 100 and not cst.not_applicable

    items, st = _kinds(_retyped(SIM_TLOG, tmp_path / "water.tlog", mav_type))
    assert not any(isinstance(s, (BaroHeight, GnssHeight, RangeHeight)) for s in items)
    assert st.filtered["vehicle_class"] >= n_height
    assert word in st.not_applicable
    said = [s for s in items if isinstance(s, Notice) and s.kind == "not_applicable"]
    assert len(said) == 1 and word in said[0].text
    # the IMU is untouched: only the height model does not fit
    assert st.samples["imu"] == cst.samples["imu"]


@pytest.mark.slow
def test_water_vehicle_audit_has_no_alarm(tmp_path):
    control = audit_file(SIM_TLOG, config_from_dict({}))
    assert control["height_integrity_applies"] and control["epochs"] > 0
    r = audit_file(_retyped(SIM_TLOG, tmp_path / "sub.tlog", 12), config_from_dict({}))
    assert r["height_integrity_applies"] is False
    assert r["alarms"] == [] and r["epochs"] == 0
    assert any("does not apply to a submarine" in n for n in r["notes"])


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not ARDUSUB.is_file(), reason="shared/tlogs not beside the checkout")
def test_real_ardusub_is_not_applicable():
    r = audit_file(ARDUSUB, config_from_dict({}))
    assert r["height_integrity_applies"] is False
    assert r["alarms"] == []
    assert r["ingest"]["filtered"]["vehicle_class"] > 1000
