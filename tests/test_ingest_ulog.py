"""PX4 ULog decoder (mavnav.ingest.onboard.ulog) against pyulog itself.

Real logs: the committed ones in ../shared/flightlogs (skipped when absent).
Every count and value below is worked out here, from ``pyulog.ULog``
directly, with the decoder's documented filters; the damage tests cut and
bit-flip copies of real logs (fixed cut points and seeds) and feed
hand-built byte strings that made pyulog itself hang or raise.
"""

from __future__ import annotations

import random
import struct
import threading
from pathlib import Path

import numpy as np
import pytest

from mavnav.errors import InputError
from mavnav.ingest.onboard import ulog as ulog_mod
from mavnav.ingest.onboard.ulog import read_ulog
from tests.support.paths import SHARED_FLIGHTLOGS

pyulog = pytest.importorskip("pyulog")

LOGS = SHARED_FLIGHTLOGS

# file -> (firmware, vehicle, baro instance, baro instances, GNSS topic or None, has rangefinder)
EXPECTED = {
    "aut_plane_plexus.ulg": ("PX4 v1.17.0 (alpha)", "plane", 0, 2, None, False),
    "aut_quad_v6xrt.ulg": ("PX4 v1.17.0 (RC)", "copter", 1, 2, "vehicle_gps_position", False),
    "aut_quadrotor_local.ulg": ("PX4 v1.16.1 (RC)", "copter", 0, 1, "vehicle_gps_position", False),
    "frs_battery_brownout.ulg": ("PX4 v1.15.1", "copter", 0, 1, None, False),
    "frs_gps_interference.ulg": ("PX4 v1.16.0", "copter", 0, 2, "vehicle_gps_position", False),
    "frs_motor_failure_hexa.ulg": ("PX4 v1.9.0 (beta)", "copter", 0, 1, "vehicle_gps_position", True),
}
AT_REST_AT_START = ("aut_quad_v6xrt.ulg", "aut_quadrotor_local.ulg", "frs_gps_interference.ulg")


def log_path(name: str) -> Path:
    p = LOGS / name
    if not p.is_file():
        pytest.skip(f"committed flight log {p} not present (needs /work/shared/flightlogs next to the repo)")
    return p


_decoded: dict = {}


def decoded(name: str):
    """(record, {(topic, multi_id): data dict} from an unfiltered pyulog load), once per file."""
    if name not in _decoded:
        p = log_path(name)
        u = pyulog.ULog(str(p), None, True)
        _decoded[name] = (read_ulog(p), {(d.name, d.multi_id): d.data for d in u.data_list}, u)
    return _decoded[name]


def sample_times(d) -> np.ndarray:
    t = d["timestamp"].astype(np.int64)
    if "timestamp_sample" in d:
        ts = d["timestamp_sample"].astype(np.int64)
        t = np.where(ts > 0, ts, t)
    return t


def expected_rows(t: np.ndarray, ok: np.ndarray) -> tuple[int, int]:
    """Rows kept: a time > 0, ``ok``, first of each time. (count, log index of the earliest)."""
    first = {}
    for i, (ti, oki) in enumerate(zip(t.tolist(), ok.tolist())):
        if ti > 0 and oki and ti not in first:
            first[ti] = i
    return len(first), first[min(first)] if first else -1


def check_series_shape(s, *cols):
    assert s.t_us.dtype == np.int64
    assert np.all(np.diff(s.t_us) > 0), f"{s.name}: times not strictly increasing"
    for c in cols:
        assert len(c) == len(s.t_us)


# ---------------------------------------------------------------------------------- real logs


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_metadata_and_messages(name):
    rec, data, u = decoded(name)
    fw, vehicle, inst, insts, gnss, has_range = EXPECTED[name]
    assert rec.format == "ulog" and rec.path.endswith(name)
    assert (rec.firmware, rec.vehicle) == (fw, vehicle)
    assert rec.bytes_read == (LOGS / name).stat().st_size
    wanted = {"sensor_combined", "vehicle_attitude", "vehicle_air_data", "sensor_baro", "vehicle_gps_position",
              "sensor_gps", "distance_sensor", "vehicle_local_position", "home_position", "vehicle_status"}
    expect = {(n if i == 0 else f"{n}[{i}]"): len(d["timestamp"]) for (n, i), d in data.items() if n in wanted}
    assert rec.messages == expect
    assert (rec.baro.instance, rec.baro.instances) == (inst, insts)
    assert (rec.gnss.name if rec.gnss is not None else None) == gnss
    assert (rec.rangefinder is not None) == has_range
    assert rec.imu.name == "sensor_combined" and rec.attitude.name == "vehicle_attitude"
    assert rec.autopilot.name == "vehicle_local_position" and rec.autopilot.datum == "ekf_origin"


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_imu_and_attitude_match_pyulog(name):
    rec, data, _ = decoded(name)
    d = data[("sensor_combined", 0)]
    t = d["timestamp"].astype(np.int64) + d["accelerometer_timestamp_relative"].astype(np.int64)
    acc = np.column_stack([d[f"accelerometer_m_s2[{i}]"].astype(float) for i in range(3)])
    n, i0 = expected_rows(t, np.isfinite(acc).all(axis=1))
    imu = rec.imu
    check_series_shape(imu, imu.fx_mps2, imu.fy_mps2, imu.fz_mps2)
    assert len(imu.t_us) == n
    assert imu.t_us[0] == t[i0]
    assert (imu.fx_mps2[0], imu.fy_mps2[0], imu.fz_mps2[0]) == tuple(acc[i0])

    a = data[("vehicle_attitude", 0)]
    ta = sample_times(a)
    q = np.column_stack([a[f"q[{i}]"].astype(float) for i in range(4)])
    norm = np.linalg.norm(q, axis=1)
    n, i0 = expected_rows(ta, np.isfinite(q).all(axis=1) & (np.abs(norm - 1) <= 0.1))
    att = rec.attitude
    check_series_shape(att, att.q)
    assert len(att.t_us) == n and att.q.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(att.q, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(att.q[0], q[i0] / norm[i0], atol=1e-12)
    assert att.t_us[0] == ta[i0] and att.t_us[-1] == ta.max()  # timestamp_sample, the estimate's time


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", AT_REST_AT_START)
def test_imu_reads_gravity_at_rest(name):
    imu = decoded(name)[0].imu
    first_s = imu.t_us - imu.t_us[0] < 1_000_000
    f = np.sqrt(imu.fx_mps2 ** 2 + imu.fy_mps2 ** 2 + imu.fz_mps2 ** 2)[first_s]
    assert f.size > 50
    assert abs(np.median(f) - 9.81) < 0.3
    assert np.median(imu.fz_mps2[first_s]) < -9.0  # FRD: specific force points up, z is down


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_baro_matches_pyulog(name):
    rec, data, _ = decoded(name)
    b = rec.baro
    check_series_shape(b, b.pressure_pa)
    d = data[("vehicle_air_data", 0)]  # every committed log has it: the estimator's baro
    assert b.name == "vehicle_air_data"
    t = sample_times(d)
    p = d["baro_pressure_pa"].astype(float)
    n, i0 = expected_rows(t, np.isfinite(p))
    assert len(b.t_us) == n
    assert b.t_us[0] == t[i0] and b.pressure_pa[0] == p[i0]
    if "timestamp_sample" in d:  # the sample time, ~20 ms before vehicle_air_data is published
        assert b.t_us[0] < d["timestamp"][i0]
    last = max(range(len(t)), key=lambda i: (t[i], -i))
    assert b.pressure_pa[-1] == p[last]
    assert 50_000 < np.median(b.pressure_pa) < 110_000  # Pa
    if b.instances > 1:  # the instance is the sensor_baro whose device id vehicle_air_data names
        assert data[("sensor_baro", b.instance)]["device_id"][0] == d["baro_device_id"][0]


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(n for n, e in EXPECTED.items() if e[4]))
def test_gnss_matches_pyulog(name):
    rec, data, _ = decoded(name)
    g = rec.gnss
    check_series_shape(g, g.alt_msl_m, g.sigma_m, g.fix_type, g.satellites)
    d = data[(g.name, 0)]
    alt = d["altitude_msl_m"].astype(float) if "altitude_msl_m" in d else d["alt"].astype(float) / 1000.0
    t = sample_times(d)
    n, i0 = expected_rows(t, np.isfinite(alt))
    assert len(g.t_us) == n and g.t_us[0] == t[i0]
    assert g.alt_msl_m[0] == pytest.approx(alt[i0], abs=1e-9)
    assert g.fix_type[0] == d["fix_type"][i0] and g.satellites[0] == d["satellites_used"][i0]
    epv = float(d["epv"][i0])
    assert g.sigma_m[0] == pytest.approx(epv) if epv > 0 else np.isnan(g.sigma_m[0])
    assert set(np.unique(g.fix_type)) == set(np.unique(d["fix_type"]).tolist())  # every fix type kept


@pytest.mark.realdata
@pytest.mark.slow
def test_rangefinder_matches_pyulog():
    rec, data, _ = decoded("frs_motor_failure_hexa.ulg")
    r = rec.rangefinder
    check_series_shape(r, r.range_m, r.min_m, r.max_m, r.valid)
    d = data[("distance_sensor", 0)]
    down = d["orientation"] == 25
    n, i0 = expected_rows(sample_times(d), down & np.isfinite(d["current_distance"].astype(float)))
    assert r.name == "distance_sensor" and len(r.t_us) == n == 361
    assert r.range_m[0] == float(d["current_distance"][i0])
    assert (r.min_m[0], r.max_m[0]) == (float(d["min_distance"][i0]), float(d["max_distance"][i0]))
    assert r.valid.dtype == bool and r.valid.all() == bool(np.all(d["signal_quality"][down] != 0))


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_autopilot_home_origin_match_pyulog(name):
    rec, data, _ = decoded(name)
    d = data[("vehicle_local_position", 0)]
    a = rec.autopilot
    check_series_shape(a, a.height_up_m)
    t = sample_times(d)
    z = d["z"].astype(float)
    n, i0 = expected_rows(t, np.isfinite(z) & (d["z_valid"] != 0 if "z_valid" in d else True))
    assert len(a.t_us) == n
    assert a.t_us[0] == t[i0] and a.height_up_m[0] == -z[i0]
    ok = [i for i in range(len(t)) if d["z_global"][i] and np.isfinite(d["ref_alt"][i])]
    if ok:
        last = max(ok, key=lambda i: d["timestamp"][i])
        assert rec.origin_alt_msl_m == pytest.approx(float(d["ref_alt"][last]))
    else:
        assert rec.origin_alt_msl_m is None
    h = data.get(("home_position", 0))
    # the first valid home in the log's time (a row stamped before the log began
    # wraps to a negative int64): where the vehicle armed
    ok = [] if h is None else [i for i in range(len(h["alt"]))
                               if h["valid_alt"][i] and np.int64(h["timestamp"][i].astype(np.int64)) > 0]
    if ok:
        first = min(ok, key=lambda i: int(h["timestamp"][i]))
        assert rec.home_alt_msl_m == pytest.approx(float(h["alt"][first]))
    else:
        assert rec.home_alt_msl_m is None


@pytest.mark.realdata
def test_a_vehicle_on_the_ground_at_the_start_is_at_its_home():
    # aut_quad_v6xrt sets home five times; its last (503 s, after the landing) lies
    # 0.5 m below the point it took off from: against it the vehicle read 0.5 m off on the ground
    rec, data, _ = decoded("aut_quad_v6xrt.ulg")
    d = data[("vehicle_local_position", 0)]
    h = data[("home_position", 0)]
    z0 = -float(d["z"][0])
    assert abs(z0 - (rec.home_alt_msl_m - rec.origin_alt_msl_m)) < 0.2
    assert abs(z0 - (float(h["alt"][-1]) - rec.origin_alt_msl_m)) > 0.4


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_damage_lines(name):
    rec, data, u = decoded(name)
    if name == "aut_plane_plexus.ulg":  # three pieces of the flight, stored out of time order
        back = [x for x in rec.damage if "time went backwards 2 time(s)" in x]
        assert {x.split(":")[0] for x in back} == {"sensor_combined", "vehicle_attitude", "vehicle_air_data",
                                                   "vehicle_local_position"}
        assert any(x.startswith("corrupt data skipped") for x in rec.damage)
    elif name == "aut_quad_v6xrt.ulg":  # an unregistered message id
        assert rec.damage == ["corrupt data skipped by pyulog (no subscription found for message id 32812)"]
    else:
        assert rec.damage == [] and not u.file_corruption and not u.dropouts


@pytest.mark.realdata
@pytest.mark.slow
def test_pyulog_warnings_do_not_reach_stdout(capsys):
    read_ulog(log_path("aut_quad_v6xrt.ulg"))
    out = capsys.readouterr().out
    assert "subscription" not in out and out == ""


# ---------------------------------------------------------------------------------- damaged copies


def _read_or_input_error(path: Path):
    try:
        return read_ulog(path)
    except InputError as exc:
        assert str(path) in str(exc) and "\n" not in str(exc)
        return None


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", ["frs_motor_failure_hexa.ulg", "aut_quadrotor_local.ulg"])
def test_truncated_copies(tmp_path, name):
    src = log_path(name)
    raw = src.read_bytes()
    full = decoded(name)[0]
    for cut in (0, 10, 16, 100, 2_000, 40_000, int(len(raw) * 0.31), int(len(raw) * 0.77), len(raw) - 1):
        p = tmp_path / f"cut_{cut}.ulg"
        p.write_bytes(raw[:cut])
        rec = _read_or_input_error(p)
        if cut < 16:
            assert rec is None, f"{cut}-byte file must be refused"
            continue
        assert rec is not None, f"cut at {cut}: a damaged ULog must still give a record"
        assert rec.damage, f"cut at {cut} removed data but no damage is reported"
        assert rec.bytes_read == cut
        for key in ("imu", "attitude", "baro", "gnss", "rangefinder", "autopilot"):
            s, f = getattr(rec, key), getattr(full, key)
            if s is not None:  # a prefix of the full log: never a sample the full log lacks
                assert np.all(np.diff(s.t_us) > 0)
                assert len(s.t_us) <= len(f.t_us) and np.isin(s.t_us, f.t_us).all()
    rec = read_ulog(p)  # the last one: all but one byte
    assert len(rec.imu.t_us) >= len(full.imu.t_us) - 1


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name,seed,flips", [
    ("frs_motor_failure_hexa.ulg", 1, 1), ("frs_motor_failure_hexa.ulg", 2, 8),
    ("frs_motor_failure_hexa.ulg", 3, 64), ("frs_motor_failure_hexa.ulg", 4, 512),
    ("aut_quad_v6xrt.ulg", 5, 1), ("aut_quad_v6xrt.ulg", 6, 16), ("aut_quad_v6xrt.ulg", 7, 200),
    ("aut_plane_plexus.ulg", 8, 4), ("aut_plane_plexus.ulg", 9, 50),
])
def test_bit_flipped_copies(tmp_path, name, seed, flips):
    raw = bytearray(log_path(name).read_bytes())
    rng = random.Random(seed)
    for k in range(4):
        b = bytearray(raw)
        for _ in range(flips):  # half in the definitions (first 150 kB), half anywhere
            i = rng.randrange(16, 150_000) if rng.random() < 0.5 else rng.randrange(16, len(b))
            b[i] ^= 1 << rng.randrange(8)
        p = tmp_path / f"flip_{seed}_{k}.ulg"
        p.write_bytes(bytes(b))
        rec = _read_or_input_error(p)
        if rec is not None:
            for s in (rec.imu, rec.attitude, rec.baro, rec.gnss, rec.rangefinder, rec.autopilot):
                if s is not None:
                    assert np.all(np.diff(s.t_us) > 0) and s.t_us.dtype == np.int64
            if rec.attitude is not None and len(rec.attitude.t_us):
                np.testing.assert_allclose(np.linalg.norm(rec.attitude.q, axis=1), 1.0, atol=1e-9)


def test_not_a_ulog(tmp_path):
    cases = {"empty.ulg": b"", "text.ulg": b"hello, this is not a log\n" * 10,
             "almost.ulg": b"ULog\x01\x12\x36" + bytes(100), "short.ulg": b"ULog\x01"}
    for fname, content in cases.items():
        p = tmp_path / fname
        p.write_bytes(content)
        with pytest.raises(InputError) as ei:
            read_ulog(p)
        assert str(p) in str(ei.value) and "\n" not in str(ei.value)
    with pytest.raises(InputError, match="missing.ulg: no such file"):
        read_ulog(tmp_path / "missing.ulg")
    with pytest.raises(InputError, match="is a directory, not a ULog"):
        read_ulog(tmp_path)
    bin_log = LOGS / "dkla_log171.bin"
    if bin_log.is_file():
        with pytest.raises(InputError, match="not a PX4 ULog"):
            read_ulog(bin_log)


# ---------------------------------------------------------------------------------- hand-built ULogs


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _ulog(*messages: bytes) -> bytes:
    flags = _msg("B", bytes(40))
    return b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0) + flags + b"".join(messages)


def _fmt(text: str) -> bytes:
    return _msg("F", text.encode())


def _add(multi_id: int, msg_id: int, name: str) -> bytes:
    return _msg("A", struct.pack("<BH", multi_id, msg_id) + name.encode())


def _data(msg_id: int, payload: bytes) -> bytes:
    return _msg("D", struct.pack("<H", msg_id) + payload)


BARO_FMT = "sensor_baro:uint64_t timestamp;uint32_t device_id;float pressure;"
DIST_FMT = "distance_sensor:uint64_t timestamp;float min_distance;float max_distance;float current_distance;" \
           "int8_t signal_quality;uint8_t orientation;"
LPOS_FMT = "vehicle_local_position:uint64_t timestamp;float z;float ref_alt;bool z_valid;bool z_global;"
GPS_FMT = "sensor_gps:uint64_t timestamp;uint64_t timestamp_sample;int32_t alt;float epv;uint8_t fix_type;" \
          "uint8_t satellites_used;"


def test_handbuilt_units_filters_and_choices(tmp_path):
    def baro(t, p):
        return struct.pack("<QIf", t, 7, p)

    def dist(t, r, q, o):
        return struct.pack("<QfffbB", t, 0.1, 20.0, r, q, o)

    def lpos(t, z, ref, zv, zg):
        return struct.pack("<QffBB", t, z, ref, zv, zg)

    def gps(t, alt_mm, epv, fix):
        return struct.pack("<QQifBB", t, 0, alt_mm, epv, fix, 9)

    body = [_fmt(BARO_FMT), _fmt(DIST_FMT), _fmt(LPOS_FMT), _fmt(GPS_FMT),
            _add(0, 1, "sensor_baro"), _add(0, 2, "distance_sensor"), _add(1, 3, "distance_sensor"),
            _add(0, 4, "vehicle_local_position"), _add(0, 5, "sensor_gps"), _add(1, 6, "sensor_gps")]
    # millibar pressures (PX4 <= 1.11), one repeated time, one NaN, out of order
    body += [_data(1, baro(t, p)) for t, p in ((3000, 1001.0), (1000, 1000.0), (2000, 1000.5),
                                             (2000, 999.0), (4000, float("nan")))]
    # instance 0: one downward row; instance 1: three downward rows (chosen) and a forward one
    body += [_data(2, dist(1000, 5.0, 100, 25))]
    body += [_data(3, dist(t, r, q, o)) for t, r, q, o in ((1000, 1.0, -1, 25), (1500, 9.0, 100, 0),
                                                        (2000, 2.0, 0, 25), (3000, 3.0, 50, 25))]
    body += [_data(4, lpos(t, z, ref, zv, zg)) for t, z, ref, zv, zg in (
        (1000, -1.0, float("nan"), 1, 0), (2000, -2.0, 400.0, 0, 1), (3000, -3.0, 401.0, 1, 1),
        (4000, -4.0, 999.0, 1, 0))]
    body += [_data(5, gps(t, a, e, f)) for t, a, e, f in ((1000, 123456, 0.0, 0), (2000, 123556, 1.5, 3))]
    body += [_data(6, gps(1500, 1, 1.0, 3))]
    p = tmp_path / "built.ulg"
    p.write_bytes(_ulog(*body))
    rec = read_ulog(p)

    b = rec.baro
    assert (b.name, b.instance, b.instances) == ("sensor_baro", 0, 1)
    assert b.t_us.tolist() == [1000, 2000, 3000]
    assert b.pressure_pa.tolist() == pytest.approx([100000.0, 100050.0, 100100.0])  # hPa -> Pa
    assert any(x.startswith("sensor_baro: time went backwards") and "2 record(s) dropped (1 non-finite or "
               "invalid, 1 repeating a time)" in x for x in rec.damage)

    r = rec.rangefinder
    assert r.name == "distance_sensor[1]" and r.t_us.tolist() == [1000, 2000, 3000]
    assert r.range_m.tolist() == [1.0, 2.0, 3.0] and r.valid.tolist() == [True, False, True]
    assert r.min_m.tolist() == pytest.approx([0.1] * 3) and r.max_m.tolist() == [20.0] * 3

    a = rec.autopilot
    assert a.t_us.tolist() == [1000, 3000, 4000] and a.height_up_m.tolist() == [1.0, 3.0, 4.0]
    assert rec.origin_alt_msl_m == 401.0  # the latest row whose reference is valid
    assert rec.home_alt_msl_m is None and rec.imu is None and rec.vehicle == "" and rec.firmware == ""

    g = rec.gnss
    assert g.name == "sensor_gps" and g.alt_msl_m.tolist() == pytest.approx([123.456, 123.556])
    assert np.isnan(g.sigma_m[0]) and g.sigma_m[1] == 1.5 and g.fix_type.tolist() == [0, 3]
    assert rec.messages == {"sensor_baro": 5, "distance_sensor": 1, "distance_sensor[1]": 4,
                            "vehicle_local_position": 4, "sensor_gps": 2, "sensor_gps[1]": 1}


def _baro_log(n: int) -> list:
    return [_fmt(BARO_FMT), _add(0, 1, "sensor_baro")] + [
        _data(1, struct.pack("<QIf", 1000 * (i + 1), 7, 100000.0 + i)) for i in range(n)]


def test_handbuilt_pyulog_recursion_is_damage(tmp_path):
    """A format that contains itself: pyulog raises RecursionError mid-file."""
    p = tmp_path / "recursion.ulg"
    p.write_bytes(_ulog(_fmt("loop:uint64_t timestamp;loop x;"), *_baro_log(10), _add(0, 2, "loop"),
                        *_baro_log(5)[2:]))
    with pytest.raises(RecursionError):
        pyulog.ULog(str(p), None, True)
    rec = read_ulog(p)
    assert len(rec.baro.t_us) == 10
    assert len(rec.damage) == 1 and rec.damage[0].startswith("pyulog failed at byte")
    q = tmp_path / "recursion_first.ulg"  # nothing usable before the failure: refused
    q.write_bytes(_ulog(_fmt("loop:uint64_t timestamp;loop x;"), _add(0, 2, "loop"), *_baro_log(3)))
    with pytest.raises(InputError, match="unreadable ULog"):
        read_ulog(q)


def test_handbuilt_malformed_dropout_stops_pyulog_and_is_reported(tmp_path):
    p = tmp_path / "dropout.ulg"
    p.write_bytes(_ulog(*_baro_log(10), _msg("O", b"\x01\x02\x03"), *_baro_log(5)[2:]))
    rec = read_ulog(p)
    assert len(rec.baro.t_us) == 10
    assert any(x.startswith("pyulog stopped at byte") for x in rec.damage)
    ok = tmp_path / "dropout_ok.ulg"
    ok.write_bytes(_ulog(*_baro_log(10), _msg("O", struct.pack("<H", 250))))
    assert read_ulog(ok).damage == ["logger dropouts: 1, 250 ms of data not logged (longest 250 ms)"]


def test_handbuilt_definitions_loop_terminates(tmp_path):
    """A corrupt header near the end of the definitions whose size reaches back
    before itself: plain pyulog scans the same bytes forever."""
    key = b"char[60000] big"
    info = _msg("I", bytes([len(key)]) + key + b"a" * 60000)
    p = tmp_path / "loop.ulg"
    p.write_bytes(_ulog(_fmt(BARO_FMT), info, struct.pack("<HB", 60000, 0), b"x" * 10))
    result = {}
    th = threading.Thread(target=lambda: result.setdefault("rec", read_ulog(p)), daemon=True)
    th.start()
    th.join(15)
    assert "rec" in result, "read_ulog did not return within 15 s"
    assert any("round in circles" in x for x in result["rec"].damage)


# ---------------------------------------------------------------------------------- bulk reader = pyulog's loop


def _ulog_state(parsed) -> dict:
    """Everything pyulog's loop leaves behind, and what the guard saw."""
    u, fh = parsed.ulog, parsed.fh
    return dict(
        data=[(d.name, d.multi_id, d.msg_id, [(k, v.dtype.str, v.tobytes()) for k, v in d.data.items()])
              for d in u.data_list],
        info=u._msg_info_dict, info_types=u._msg_info_dict_types, info_multiple=u._msg_info_multiple_dict,
        changed=u._changed_parameters, defaults=u._default_parameters,
        logged=[(m.log_level, m.timestamp, m.message) for m in u._logged_messages],
        tagged={k: [(m.log_level, m.tag, m.timestamp, m.message) for m in v]
                for k, v in u._logged_messages_tagged.items()},
        dropouts=[(d.duration, d.timestamp) for d in u._dropouts],
        corrupt=u._file_corrupt, last_timestamp=u._last_timestamp, syncs=u._sync_seq_cnt, has_sync=u._has_sync,
        missing=u._missing_message_ids, filtered=u._filtered_message_ids, printed=parsed.printed,
        cut=fh.cut, stopped_at=fh.stopped_at, gave_up_at=fh.gave_up_at, last_back=fh._last_back,
        regressions=fh._regressions)


def _records_equal(a, b) -> None:
    assert (a.firmware, a.vehicle, a.home_alt_msl_m, a.origin_alt_msl_m, a.messages, a.damage, a.bytes_read) == \
        (b.firmware, b.vehicle, b.home_alt_msl_m, b.origin_alt_msl_m, b.messages, b.damage, b.bytes_read)
    for key in ("imu", "attitude", "baro", "gnss", "rangefinder", "autopilot"):
        sa, sb = getattr(a, key), getattr(b, key)
        assert (sa is None) == (sb is None), key
        if sa is None:
            continue
        for field, va in vars(sa).items():
            vb = getattr(sb, field)
            if isinstance(va, np.ndarray):
                assert va.dtype == vb.dtype and va.tobytes() == vb.tobytes(), f"{key}.{field}"
            else:
                assert va == vb, f"{key}.{field}"


def _bulk_against_loop(p: Path):
    """The bulk reader's pyulog state and record equal pyulog's loop's; returns
    where the bulk read got to (None: not used) and whether the file was corrupt."""
    size = p.stat().st_size
    bulk = ulog_mod._load_bulk(str(p), size)
    try:
        ref, failed = ulog_mod._load(str(p), size, bulk=False)
    except InputError:
        ref, failed = None, True
    if bulk is None:
        return None, None
    assert not failed, "pyulog's loop raised where the bulk reader did not"
    assert _ulog_state(bulk) == _ulog_state(ref)
    _records_equal(read_ulog(p), read_ulog(p, bulk=False))
    return bulk.bulk_to, bulk.ulog._file_corrupt


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bulk_reader_equals_pyulog_loop(name):
    p = log_path(name)
    bulk_to, corrupt = _bulk_against_loop(p)
    assert bulk_to == p.stat().st_size, "the bulk reader must read a committed log to its end"
    assert corrupt == (name in ("aut_plane_plexus.ulg", "aut_quad_v6xrt.ulg"))  # both resync on corrupt bytes


def _data_start(p: Path) -> int:
    import pyulog.core as core

    fh = ulog_mod._open(str(p), p.stat().st_size)
    core.ULog(fh, list(ulog_mod.TOPICS), True, True)
    return fh.stopped_at


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", ["frs_gps_interference.ulg", "frs_motor_failure_hexa.ulg"])
def test_bulk_reader_equals_pyulog_loop_on_damaged_copies(tmp_path, name):
    """Flips, garbage (with and without a sync sequence), splices, zeroed runs
    and cuts in the data section; the first log has sync messages, the
    second (PX4 1.9) none, so pyulog resyncs on one and not the other."""
    src = log_path(name)
    raw = src.read_bytes()
    start = _data_start(src)
    rng = random.Random(1100)
    outcomes = []
    for k in range(24):
        b = bytearray(raw)
        kind = ("flip", "garbage", "sync", "splice", "zero", "cut")[k % 6]
        i = rng.randrange(start, len(b))
        if kind == "flip":
            for _ in range(rng.choice([1, 4, 30])):
                j = rng.randrange(start, len(b))
                b[j] ^= 1 << rng.randrange(8)
        elif kind == "garbage":
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
        elif kind == "sync":
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80))) + bytes(ulog_mod._SYNC)
        elif kind == "splice":
            del b[i:i + rng.randrange(1, 5000)]
        elif kind == "zero":
            n = min(rng.randrange(1, 2000), len(b) - i)
            b[i:i + n] = bytes(n)
        else:
            b = b[:i]
        p = tmp_path / f"{kind}_{k}.ulg"
        p.write_bytes(bytes(b))
        bulk_to, corrupt = _bulk_against_loop(p)
        outcomes.append((bulk_to == len(b), bool(corrupt)))
    assert (True, True) in outcomes, "no copy was read to its end in bulk across a resync"
    assert any(not whole for whole, _ in outcomes), "no copy was handed over to pyulog's loop"


def _baro_rows(t0: int, n: int) -> list:
    return [_data(1, struct.pack("<QIf", 1000 * (t0 + i), 7, 100000.0 + i)) for i in range(n)]


SYNC = bytes([0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12])


@pytest.mark.parametrize("case,whole,corrupt,rows", [
    ("unknown_type", True, False, 20),  # a remove-logged message: skipped by pyulog, no damage
    ("corrupt_header_then_sync", True, True, 20),  # resync after the garbage
    ("sync_inside_unknown", True, True, 20),  # resync inside an unknown message
    ("corrupt_header_no_sync", False, True, 10),  # no sync after: pyulog goes on byte by byte
    ("corrupt_header_far_sync", True, True, 20),  # the sync several of pyulog's 512-byte chunks on
    ("sync_ends_a_chunk", True, True, 20),  # ... ending exactly where pyulog's third chunk ends
    ("sync_ends_the_file", True, True, 10),
    ("dropout", True, False, 20),  # its time: the latest data time before it
    ("same_topic_twice", True, False, 14),  # sensor_baro instance 0 subscribed twice: pyulog lists the second first
])
def test_bulk_reader_follows_pyulog_recovery(tmp_path, case, whole, corrupt, rows):
    head = [_fmt(BARO_FMT), _add(0, 1, "sensor_baro"), *_baro_rows(1, 10)]
    tail = _baro_rows(11, 10)
    if case == "unknown_type":
        mid = [_msg("R", struct.pack("<H", 99))]
    elif case == "corrupt_header_then_sync":
        mid = [struct.pack("<HB", 0, 0), b"\x07" * 40, SYNC]
    elif case == "sync_inside_unknown":
        mid = [struct.pack("<HB", 29, ord("X")), b"\x01" * 10, SYNC, _msg("S", SYNC)]  # on inside it
    elif case == "corrupt_header_no_sync":
        mid = [struct.pack("<HB", 0, 0), b"\x07" * 40]
    elif case == "corrupt_header_far_sync":
        mid = [struct.pack("<HB", 0, 0), b"\x07" * 1500, SYNC]
    elif case == "sync_ends_a_chunk":  # chunks from the byte after the header, 505 bytes apart
        mid = [struct.pack("<HB", 0, 0), b"\x07" * (2 * 505 + 502), SYNC]
    elif case == "sync_ends_the_file":
        mid, tail = [struct.pack("<HB", 0, 0), b"\x07" * 700, SYNC], []
    elif case == "dropout":
        mid = [_msg("O", struct.pack("<H", 250))]
    else:
        mid = [_add(0, 2, "sensor_baro"), _data(2, struct.pack("<QIf", 500_000, 7, 90000.0))]
        tail = _baro_rows(11, 4) + [_data(2, struct.pack("<QIf", 600_000, 7, 90000.0))]
    p = tmp_path / f"{case}.ulg"
    p.write_bytes(_ulog(*head, *mid, *tail))
    bulk_to, was_corrupt = _bulk_against_loop(p)
    assert (bulk_to == p.stat().st_size, was_corrupt) == (whole, corrupt)
    assert len(read_ulog(p).baro.t_us) == rows


@pytest.mark.realdata
@pytest.mark.slow
@pytest.mark.parametrize("name", ["frs_gps_interference.ulg", "frs_motor_failure_hexa.ulg"])
def test_bulk_reader_equals_pyulog_loop_with_damaged_definitions(tmp_path, name):
    """Cuts, flips and garbage inside the header and definitions (where the
    bulk reader lets pyulog read through the file's own read and knows the
    guard's record only afterwards): the same pyulog state, guard record and
    record as pyulog's loop through the guarded file."""
    src = log_path(name)
    raw = src.read_bytes()
    start = _data_start(src)
    rng = random.Random(1500)
    fell_back = 0
    for k in range(24):
        b = bytearray(raw)
        kind = ("cut", "flip", "garbage", "cut_header")[k % 4]
        i = rng.randrange(ulog_mod.HEADER_LEN, start)
        if kind == "cut":
            b = b[:i]
        elif kind == "cut_header":
            b = b[:rng.randrange(ulog_mod.HEADER_LEN, ulog_mod.HEADER_LEN + 40)]
        elif kind == "flip":
            for _ in range(rng.choice([1, 3])):
                j = rng.randrange(ulog_mod.HEADER_LEN, start)
                b[j] ^= 1 << rng.randrange(8)
        else:
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
        p = tmp_path / f"{kind}_{k}.ulg"
        p.write_bytes(bytes(b))
        fh = ulog_mod._DefsFile(str(p), len(b))
        try:
            import pyulog.core as core

            core.ULog(fh, list(ulog_mod.TOPICS), True, True)
            fell_back += not fh.whole()
        except Exception:
            fell_back += 1
        _bulk_against_loop(p)
    assert fell_back >= 6, "the guarded re-read of the definitions was not exercised"


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["frs_motor_failure_hexa.ulg", "aut_quad_v6xrt.ulg"])
def test_definitions_read_whole_give_the_guarded_state(name):
    """On a healthy log the definitions are read through the file's own read
    (one seek back, before the end) and leave pyulog and the guard as the
    guarded file does."""
    import pyulog.core as core

    p = log_path(name)
    size = p.stat().st_size
    fast, guarded = ulog_mod._DefsFile(str(p), size), ulog_mod._open(str(p), size)
    a = core.ULog(fast, list(ulog_mod.TOPICS), True, True)
    b = core.ULog(guarded, list(ulog_mod.TOPICS), True, True)
    assert fast.whole()
    assert (a._msg_info_dict, a._initial_parameters, sorted(a._message_formats)) == \
        (b._msg_info_dict, b._initial_parameters, sorted(b._message_formats))
    assert (fast.cut, fast.stopped_at, fast.gave_up_at, fast._last_back, fast._regressions) == \
        (guarded.cut, guarded.stopped_at, guarded.gave_up_at, guarded._last_back, guarded._regressions)
