"""``inject``: byte-identical outside the fault window, the fault applied inside it.

Logs are decoded with pymavlink (``mavutil``, robust parsing: corrupt bytes
come back as BAD_DATA), never with mavnav's own splitter.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest
from click.testing import CliRunner

from mavnav.atmosphere import P0_PA, height_from_pressure_m
from mavnav.cli import main
from mavnav.errors import ConfigError, InputError
from mavnav.frames import down_row_from_euler
from mavnav.sim import parse_fault, scenario_from_dict, simulate
from mavnav.sim.inject import inject_bytes
from tests.support.tlog_decode import decode
from tests.support.paths import SHARED_TLOGS

TLOGS = SHARED_TLOGS


def _rec(m) -> bytes:
    return struct.pack(">Q", round(m._timestamp * 1e6)) + bytes(m.get_msgbuf())


def strip(data: bytes, msgs) -> bytes:
    """``data`` without the records of ``msgs`` (in file order)."""
    parts, pos = [], 0
    for m in msgs:
        rec = _rec(m)
        i = data.find(rec, pos)
        assert i >= 0
        parts.append(data[pos:i])
        pos = i + len(rec)
    parts.append(data[pos:])
    return b"".join(parts)


def _t(m):
    return m.time_boot_ms / 1e3 if hasattr(m, "time_boot_ms") else m.time_usec / 1e6


@pytest.fixture(scope="module")
def px4_log():
    scn = scenario_from_dict({
        "duration_s": 30, "seed": 9, "profile": "px4",
        "trajectory": {"kind": "hover", "height_m": 10, "takeoff": False},
        "rates_hz": {"HIGHRES_IMU": 50},
    })
    return simulate(scn).tlog


def _field_dict(m):
    d = m.to_dict()
    d.pop("mavpackettype")
    return d


def test_gnss_step_on_simulated_log(tmp_path, px4_log):
    f = parse_fault("gnss_step:onset=12,duration=6,magnitude=10")
    out, report = inject_bytes(px4_log, [f])
    a, b = decode(tmp_path, px4_log, "a.tlog"), decode(tmp_path, out, "b.tlog")
    assert len(a) == len(b)
    hit = 0
    for x, y in zip(a, b):
        assert x._timestamp == y._timestamp and x.get_type() == y.get_type()
        inside = x.get_type() == "GPS_RAW_INT" and 12.0 <= _t(x) < 18.0
        if not inside:
            assert bytes(x.get_msgbuf()) == bytes(y.get_msgbuf())
            continue
        hit += 1
        assert (y.get_seq(), y.get_srcSystem(), y.get_srcComponent()) == (x.get_seq(), x.get_srcSystem(), x.get_srcComponent())
        assert y.get_msgbuf()[0] == x.get_msgbuf()[0]
        dx, dy = _field_dict(x), _field_dict(y)
        assert dy.pop("alt") - dx.pop("alt") == 10000  # mm
        assert dy.pop("alt_ellipsoid") - dx.pop("alt_ellipsoid") == 10000
        assert dx == dy
    assert hit == pytest.approx(60, abs=2)  # 10 Hz for 6 s
    # nothing else in the file: the output is exactly its records
    assert out == b"".join(_rec(m) for m in b)
    rep = report["faults"][0]
    assert rep["records_modified"] == hit and rep["boot"] == 0 and rep["source"] == "gnss"


def test_accel_bias_step_adds_to_the_vertical_specific_force(tmp_path, px4_log):
    out, _ = inject_bytes(px4_log, [parse_fault("accel_bias_step:onset=5,duration=4,magnitude=0.5")])
    a, b = decode(tmp_path, px4_log, "a.tlog"), decode(tmp_path, out, "b.tlog")
    att = (0.0, 0.0)
    n = 0
    for x, y in zip(a, b):
        if x.get_type() == "ATTITUDE":
            att = (x.roll, x.pitch)
        if x.get_type() != "HIGHRES_IMU":
            assert bytes(x.get_msgbuf()) == bytes(y.get_msgbuf())
            continue
        d = np.array([y.xacc - x.xacc, y.yacc - x.yacc, y.zacc - x.zacc])
        if 5.0 <= _t(x) < 9.0:
            n += 1
            assert -np.dot(down_row_from_euler(*att), d) == pytest.approx(0.5, abs=2e-5)  # float32
            assert np.linalg.norm(d) == pytest.approx(0.5, abs=2e-5)
        else:
            assert not d.any()
    assert n == pytest.approx(200, abs=2)


@pytest.mark.slow
def test_link_loss_and_reboot_on_simulated_log(tmp_path, px4_log):
    out, rep = inject_bytes(px4_log, [parse_fault("link_loss:onset=5,duration=2"),
                                      parse_fault("reboot:onset=20,duration=3")])
    a, b = decode(tmp_path, px4_log, "a.tlog"), decode(tmp_path, out, "b.tlog")
    timed_b = [m for m in b if hasattr(m, "time_boot_ms") or hasattr(m, "time_usec")]
    assert not [m for m in timed_b if 5.0 <= _t(m) < 7.0 and m._timestamp < a[0]._timestamp + 10]
    # after the reboot window the boot clock restarted at the onset (20 s): times 3..10 s
    late = [m for m in b if m._timestamp > a[0]._timestamp + 20.5 and m.get_type() == "ATTITUDE"]
    assert late and 2.9 < _t(late[0]) < 3.2 and max(_t(m) for m in late) < 10.05
    # records before the link loss are untouched, byte for byte
    early_a = [m for m in a if m._timestamp < a[0]._timestamp + 4.9]
    assert [bytes(m.get_msgbuf()) for m in early_a] == [bytes(m.get_msgbuf()) for m in b[: len(early_a)]]
    dropped = {f["kind"]: f["records_dropped"] for f in rep["faults"]}
    assert dropped["link_loss"] > 0 and dropped["reboot"] > 0


def test_rangefinder_dropout_on_ardupilot_log(tmp_path):
    scn = scenario_from_dict({"duration_s": 20, "profile": "ardupilot", "seed": 2,
                              "trajectory": {"kind": "hover", "height_m": 8, "takeoff": False}})
    data = simulate(scn).tlog
    out, _ = inject_bytes(data, [parse_fault("rng_dropout:onset=6,duration=4,mode=invalid"),
                                 parse_fault("rng_dropout:onset=12,duration=3,mode=silent")])
    a, b = decode(tmp_path, data, "a.tlog"), decode(tmp_path, out, "b.tlog")
    ds = [m for m in b if m.get_type() == "DISTANCE_SENSOR"]
    inval = [m for m in ds if 6 <= _t(m) < 10]
    assert inval and all(m.signal_quality == 1 and m.current_distance > m.max_distance for m in inval)
    assert not [m for m in ds if 12 <= _t(m) < 15]
    assert [m for m in ds if _t(m) >= 15]
    n_rf = lambda ms: sum(m.get_type() == "RANGEFINDER" for m in ms)  # noqa: E731
    assert n_rf(a) - n_rf(b) == pytest.approx(30, abs=2)  # 10 Hz for 3 s removed
    rf_b = [m.distance for m in b if m.get_type() == "RANGEFINDER"]
    assert max(rf_b) > scn.sensors.rangefinder.max_m
    untouched = [m for m in a if m.get_type() not in ("DISTANCE_SENSOR", "RANGEFINDER")]
    assert [bytes(m.get_msgbuf()) for m in untouched] == [
        bytes(m.get_msgbuf()) for m in b if m.get_type() not in ("DISTANCE_SENSOR", "RANGEFINDER")]


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not (TLOGS / "real" / "dronekit_copter_2015.tlog").exists(), reason="shared tlogs absent")
def test_baro_step_on_a_real_log_with_corrupt_frames_and_a_reboot(tmp_path):
    data = (TLOGS / "real" / "dronekit_copter_2015.tlog").read_bytes()
    out, rep = inject_bytes(data, [parse_fault("baro_step:onset=100,duration=20,magnitude=5")])
    a, b = decode(tmp_path, data, "a.tlog"), decode(tmp_path, out, "b.tlog")
    assert sum(m.get_type() == "BAD_DATA" for m in a) > 100  # the log's own radio damage
    assert [m.get_type() for m in a] == [m.get_type() for m in b]
    # the faulted records: SCALED_PRESSURE of the first boot with 100 <= t < 120
    sp_a = [m for m in a if m.get_type() == "SCALED_PRESSURE"]
    sp_b = [m for m in b if m.get_type() == "SCALED_PRESSURE"]
    t = np.array([m.time_boot_ms for m in sp_a]) / 1e3
    first_boot_end = int(np.argmax(np.diff(t) < -10)) + 1  # the log's reboot
    idx = [i for i in range(first_boot_end) if 100 <= t[i] < 120]
    assert len(idx) > 20 and any(100 <= t[i] < 120 for i in range(first_boot_end, len(t)))
    for i in range(len(sp_a)):
        x, y = sp_a[i], sp_b[i]
        if i in idx:
            dh = height_from_pressure_m(y.press_abs * 100, P0_PA) - height_from_pressure_m(x.press_abs * 100, P0_PA)
            assert dh == pytest.approx(5.0, abs=0.02)  # float32 hPa
            assert (y.get_seq(), y.get_srcSystem(), y.get_srcComponent()) == (x.get_seq(), x.get_srcSystem(), x.get_srcComponent())
            assert y.get_msgbuf()[0] == x.get_msgbuf()[0]
        else:
            assert bytes(x.get_msgbuf()) == bytes(y.get_msgbuf())
    # every other byte, corrupt frames and their timestamps included, is unchanged
    assert strip(data, [sp_a[i] for i in idx]) == strip(out, [sp_b[i] for i in idx])
    assert rep["faults"][0]["records_modified"] == len(idx) and rep["faults"][0]["boot"] == 0
    assert rep["junk_records"] > 100


def _v1_without_extensions(buf: bytes) -> bytes:
    """A MAVLink 1 GPS_RAW_INT as a v1-only autopilot sends it: the 30-byte base payload."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2

    payload = buf[6 : 6 + 30]
    header = bytes((0xFE, 30)) + buf[2:6]
    crc = mav2.x25crc(header[1:] + payload)
    crc.accumulate(bytes((mav2.MAVLink_gps_raw_int_message.crc_extra,)))
    return header + payload + struct.pack("<H", crc.crc)


def _mixed_version_log() -> bytes:
    """ATTITUDE (v2) at 10 Hz; GPS_RAW_INT in MAVLink 2, in MAVLink 1 with its extensions
    (as pymavlink sends it) and in MAVLink 1 without them, in turn."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2

    parts = []
    link = mav2.MAVLink(None, srcSystem=7, srcComponent=1)
    for k in range(120):
        t = struct.pack(">Q", 1717236000_000000 + k * 100_000)
        att = mav2.MAVLink_attitude_message(k * 100, 0.1, -0.05, 1.0, 0.0, 0.0, 0.0)
        parts.append(t + att.pack(link))
        link.seq = (link.seq + 1) % 256
        gps = mav2.MAVLink_gps_raw_int_message(k * 100_000, 3, 473977420, 85455940, 500_000 + k, 70, 110,
                                               0, 0, 12, 547_000 + k, 500, 900, 300, 0, 0)
        buf = gps.pack(link, force_mavlink1=(k % 3 != 0))
        parts.append(t + (_v1_without_extensions(buf) if k % 3 == 2 else buf))
        link.seq = (link.seq + 1) % 256
    return b"".join(parts)


def test_mavlink1_frames_stay_mavlink1(tmp_path):
    data = _mixed_version_log()
    out, rep = inject_bytes(data, [parse_fault("gnss_ramp:onset=2,duration=5,magnitude=0.5")])
    a, b = decode(tmp_path, data, "a.tlog"), decode(tmp_path, out, "b.tlog")
    assert "BAD_DATA" not in {m.get_type() for m in b}  # every re-framed CRC checks
    assert len(a) == len(b)
    versions = set()
    for x, y in zip(a, b):
        if x.get_type() != "GPS_RAW_INT" or not 2 <= _t(x) < 7:
            assert bytes(x.get_msgbuf()) == bytes(y.get_msgbuf())
            continue
        v = x.get_msgbuf()[0]
        versions.add(v)
        assert y.get_msgbuf()[0] == v
        assert (y.get_seq(), y.get_srcSystem(), y.get_srcComponent()) == (x.get_seq(), 7, 1)
        assert y.alt - x.alt == round(500 * (_t(x) - 2))
        assert len(y.get_msgbuf()) == len(x.get_msgbuf())  # no extension fields added or lost
        if len(x.get_msgbuf()) == 6 + 30 + 2:  # MAVLink 1 base payload: alt_ellipsoid not on the wire
            assert y.alt_ellipsoid == x.alt_ellipsoid == 0
            versions.add("v1-base")
        else:
            assert y.alt_ellipsoid - x.alt_ellipsoid == y.alt - x.alt
    assert versions == {0xFE, 0xFD, "v1-base"}
    assert rep["sysid"] == 7 and rep["faults"][0]["records_modified"] == 50


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.skipif(not (TLOGS / "other" / "copter_sitl_mixed_v1_v2.tlog").exists(), reason="shared tlogs absent")
def test_mixed_version_real_log_untouched_types_stay_identical(tmp_path):
    data = (TLOGS / "other" / "copter_sitl_mixed_v1_v2.tlog").read_bytes()
    out, rep = inject_bytes(data, [parse_fault("gnss_step:onset=0,magnitude=4")])
    a, b = decode(tmp_path, data, "a.tlog"), decode(tmp_path, out, "b.tlog")
    assert [m.get_type() for m in a] == [m.get_type() for m in b]  # no CRC failures introduced
    changed = [y for x, y in zip(a, b) if bytes(x.get_msgbuf()) != bytes(y.get_msgbuf())]
    assert changed and {m.get_type() for m in changed} == {"GPS_RAW_INT"}
    assert len(changed) == rep["faults"][0]["records_modified"]
    v1 = [m for m in a if m.get_msgbuf()[0] == 0xFE]
    assert len(v1) > 1000  # PARAM_VALUE in MAVLink 1, untouched


def test_fault_beyond_the_log_changes_nothing(px4_log):
    out, rep = inject_bytes(px4_log, [parse_fault("gnss_step:onset=1000,magnitude=3")])
    assert out == px4_log
    assert rep["faults"][0]["boot"] is None and rep["faults"][0]["records_modified"] == 0


@pytest.mark.parametrize(
    "spec,needle",
    [
        ("gnss_stpe:onset=1,magnitude=2", "unknown kind 'gnss_stpe'"),
        ("gnss_step:onset=1", "gnss_step needs a magnitude"),
        ("gnss_step:magnitude=1", "missing key 'onset'"),
        ("gnss_step:onset=1,magnitud=2", "unknown key 'magnitud'"),
        ("gnss_step:onset=x,magnitude=2", "onset_s"),
        ("rng_dropout:onset=1,mode=nofix", "rng_dropout mode must be one of"),
        ("baro_freeze:onset=1,magnitude=3", "baro_freeze takes no magnitude"),
        ("gnss_step:onset=1,magnitude", "is not key=value"),
    ],
)
def test_bad_fault_specs_are_refused_by_name(spec, needle):
    with pytest.raises(ConfigError) as exc:
        parse_fault(spec)
    assert needle in str(exc.value)


def test_not_a_tlog_is_refused():
    with pytest.raises(InputError, match="not a tlog"):
        inject_bytes(b"hello world, this is not telemetry" * 10, [parse_fault("link_loss:onset=1,duration=1")])


def test_cli_inject_writes_output_and_sidecar(tmp_path, px4_log):
    src = tmp_path / "in.tlog"
    src.write_bytes(px4_log)
    out = tmp_path / "out.tlog"
    r = CliRunner().invoke(main, ["inject", str(src), "-o", str(out),
                                  "gnss_step:onset=10,duration=5,magnitude=10", "baro_freeze:onset=20"])
    assert r.exit_code == 0, r.output
    side = json.loads((tmp_path / "out.faults.json").read_text())
    assert [f["kind"] for f in side["faults"]] == ["gnss_step", "baro_freeze"]
    assert side["faults"][0]["onset_s"] == 10 and side["faults"][0]["end_s"] == 15
    assert side["faults"][1]["end_s"] is None and side["faults"][1]["records_modified"] > 0
    assert side["sysid"] == 1 and side["input"] == str(src)
    assert out.read_bytes() != px4_log
    bad = CliRunner().invoke(main, ["inject", str(src), "-o", str(out), "gnss_step:onset=1"])
    assert bad.exit_code == 2 and "needs a magnitude" in bad.output
    assert "FAULT syntax" in CliRunner().invoke(main, ["inject", "--help"]).output
    assert math.isfinite(side["faults"][0]["first_recv_unix_s"])


def _systems_log(path, first) -> bytes:
    """Heartbeats of a ground station, a companion computer (no autopilot), a
    gimbal that names an autopilot and a quadrotor (system 1, autopilot
    component 1), in the order ``first`` then the rest, each with a few ATTITUDE frames."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2
    from tests.support.tlog_writer import TlogWriter

    systems = {  # name: (sysid, compid, MAV_TYPE, MAV_AUTOPILOT)
        "gcs": (255, 190, mav2.MAV_TYPE_GCS, mav2.MAV_AUTOPILOT_INVALID),
        "companion": (1, 191, mav2.MAV_TYPE_ONBOARD_CONTROLLER, mav2.MAV_AUTOPILOT_INVALID),
        "gimbal": (2, 154, mav2.MAV_TYPE_GIMBAL, mav2.MAV_AUTOPILOT_ARDUPILOTMEGA),
        "quad": (1, 1, mav2.MAV_TYPE_QUADROTOR, mav2.MAV_AUTOPILOT_ARDUPILOTMEGA),
    }
    order = [first] + [k for k in systems if k != first]
    with TlogWriter(path) as w:
        for k in range(40):
            for name in order:
                sysid, compid, mav_type, autopilot = systems[name]
                t = 1_700_000_000 + k * 0.1
                if k % 10 == 0:
                    w.write(w.mav.heartbeat_encode(mav_type, autopilot, 0, 0, 4, 3), t, sysid, compid)
                w.write(w.mav.attitude_encode(k * 100, 0.0, 0.0, 0.0, 0, 0, 0), t, sysid, compid)
    return path.read_bytes()


@pytest.mark.parametrize("first", ["gcs", "companion", "gimbal", "quad"])
@pytest.mark.parametrize("sysid", [None, 1])
def test_the_injector_faults_the_vehicle_the_monitor_chooses(tmp_path, first, sysid):
    from mavnav.ingest import TlogSource

    data = _systems_log(tmp_path / "systems.tlog", first)
    _, rep = inject_bytes(data, [parse_fault("gnss_step:onset=1,magnitude=3")], sysid=sysid)
    src = TlogSource(tmp_path / "systems.tlog", sysid=sysid)
    for _ in src:
        pass
    assert (rep["sysid"], rep["autopilot_compid"]) == (src.stats.vehicle.sysid, src.stats.vehicle.compid)


def test_a_message_id_above_255_is_reframed():
    """A reboot shifts every boot-time field, STORAGE_INFORMATION's (id 261, MAVLink 2 only) too."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2

    from mavnav.sim.inject import reframe

    link = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    original = bytes(mav2.MAVLink_storage_information_message(70_000, 1, 1, 2, 3.0, 1.0, 4.0, 5.0, 6.0).pack(link))
    msg = link.decode(bytearray(original))
    msg.time_boot_ms = 20_000
    out = reframe(original, msg)
    back = mav2.MAVLink(None).decode(bytearray(out))
    assert back.get_type() == "STORAGE_INFORMATION" and back.time_boot_ms == 20_000
    assert back.available_capacity == 4.0 and out[2:10] == original[2:10]
