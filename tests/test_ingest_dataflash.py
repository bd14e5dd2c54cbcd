"""ArduPilot DataFlash logs: decoded columns against pymavlink's own DFReader, the
shared onboard source, damage handling, and detection by content."""

from __future__ import annotations

import contextlib
import io
import math
import shutil

import numpy as np
import pytest

from mavnav.atmosphere import height_from_pressure_m
from mavnav.errors import InputError
from mavnav.ingest import open_log
from mavnav.ingest.logs import expand_log_paths, log_format
from mavnav.ingest.onboard.dataflash import read_dataflash
from mavnav.ingest.onboard.source import OnboardSource
from mavnav.samples import BaroHeight, GnssHeight, RangeHeight, ReferenceSet, Rejected, SpecificForceUp
from tests.support.paths import SHARED_FLIGHTLOGS

FLIGHTLOGS = SHARED_FLIGHTLOGS
BINS = sorted(p for p in FLIGHTLOGS.glob("*") if p.suffix.lower() == ".bin") if FLIGHTLOGS.is_dir() else []
pytestmark = [pytest.mark.realdata, pytest.mark.slow, pytest.mark.skipif(not BINS, reason=f"no DataFlash logs in {FLIGHTLOGS}")]


def _dfreader_rows(path, name, pred=lambda m: True):
    from pymavlink import DFReader

    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        r = DFReader.DFReader_binary(str(path), zero_time_base=True)
        rows = []
        while True:
            m = r.recv_match(type=name)
            if m is None:
                break
            if pred(m):
                rows.append(m)
    return rows


def _time_us(m) -> int:
    return int(m.TimeUS) if hasattr(m, "TimeUS") else int(m.TimeMS) * 1000


@pytest.mark.parametrize("path", BINS, ids=lambda p: p.name)
def test_columns_equal_dfreader(path):
    rec = read_dataflash(path)
    assert rec.firmware and rec.vehicle == "copter"
    baro = _dfreader_rows(path, "BARO", lambda m: getattr(m, "I", 0) == rec.baro.instance)
    assert rec.baro.t_us.size == len(baro)
    assert rec.baro.pressure_pa[0] == pytest.approx(baro[0].Press)
    assert rec.baro.pressure_pa[-1] == pytest.approx(baro[-1].Press)
    gps = _dfreader_rows(path, "GPS", lambda m: getattr(m, "I", 0) == 0)
    assert rec.gnss.t_us.size == len(gps)
    assert rec.gnss.alt_msl_m[-1] == pytest.approx(gps[-1].Alt, abs=1e-6)
    assert rec.gnss.fix_type[-1] == gps[-1].Status
    att = _dfreader_rows(path, "ATT")
    assert rec.attitude.t_us[0] == _time_us(att[0])
    for series in (rec.imu, rec.attitude, rec.baro, rec.gnss, rec.autopilot):
        assert np.all(np.diff(series.t_us) > 0)


def test_acc_fields_and_rangefinder_status_sitl():
    path = FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"
    rec = read_dataflash(path)
    imu = _dfreader_rows(path, "IMU", lambda m: m.I == 0)
    assert rec.imu.t_us.size == len(imu)
    assert rec.imu.fz_mps2[0] == pytest.approx(imu[0].AccZ)
    rf = _dfreader_rows(path, "RFND")
    assert rec.rangefinder.t_us.size == len(rf)
    # this SITL rangefinder reports 'out of range low' (status 2) all flight: never valid
    assert not rec.rangefinder.valid.any()
    assert rec.rangefinder.min_m[0] == pytest.approx(0.2) and rec.rangefinder.max_m[0] == pytest.approx(50.0)
    assert rec.home_alt_msl_m == pytest.approx(137.07, abs=0.01)


def test_gpa_vertical_accuracy_matched():
    path = FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"
    rec = read_dataflash(path)
    gpa = _dfreader_rows(path, "GPA", lambda m: m.I == 0)
    assert np.nanmedian(rec.gnss.sigma_m) == pytest.approx(np.median([m.VAcc for m in gpa]))


def test_old_gps_time_is_boot_time():
    """ArduCopter 3.3 GPS: TimeMS is GPS week time, T the boot time."""
    path = FLIGHTLOGS / "dkla_log171.bin"
    rec = read_dataflash(path)
    gps = _dfreader_rows(path, "GPS")
    assert rec.gnss.t_us[0] == gps[0].T * 1000
    assert abs(rec.gnss.t_us[0] - rec.baro.t_us[0]) < 600e6  # the same clock, not GPS time of week


@pytest.mark.parametrize("path", BINS, ids=lambda p: p.name)
def test_source_samples(path):
    src = open_log(path)
    assert isinstance(src, OnboardSource)
    out = list(src)
    f_up = np.array([s.f_up_mps2 for s in out if isinstance(s, SpecificForceUp)])
    assert 9.0 < np.median(f_up) < 10.6  # about g, up
    baro = [s for s in out if isinstance(s, BaroHeight)]
    p_ref = src.stats.references["baro"].value
    assert baro[10].height_ref_m == pytest.approx(height_from_pressure_m(baro[10].pressure_pa, p_ref))
    assert abs(np.mean([b.height_ref_m for b in baro[:5]])) < 1.0  # start-up reference
    ts = [s.t_us for s in out if getattr(s, "t_us", None) is not None and not isinstance(s, ReferenceSet)]
    assert all(a <= b for a, b in zip(ts, ts[1:]))  # merged in vehicle-time order
    assert src.stats.samples["imu"] == len(f_up)
    assert src.stats.format == "dataflash"


def test_invalid_rangefinder_readings_are_refused_as_range():
    src = open_log(FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN")
    out = list(src)
    assert not any(isinstance(s, RangeHeight) for s in out)
    rej = [s for s in out if isinstance(s, Rejected) and s.sensor == "range"]
    assert len(rej) == 974 and {s.kind for s in rej} == {"invalid_status"}


def test_detection_by_content_not_extension(tmp_path):
    src = FLIGHTLOGS / "dkla_log171.bin"
    renamed = tmp_path / "flight.tlog"
    shutil.copy(src, renamed)
    assert log_format(renamed) == "dataflash"
    assert isinstance(open_log(renamed), OnboardSource)
    (tmp_path / "sub").mkdir()
    shutil.copy(src, tmp_path / "sub" / "X.BIN")
    assert [p.name for p in expand_log_paths(tmp_path)] == ["flight.tlog", "X.BIN"]


@pytest.mark.parametrize("frac", [0.003, 0.3, 0.77, 0.999])
def test_truncated_log_is_read_up_to_the_cut(tmp_path, frac):
    src = FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"
    data = src.read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(data[: int(len(data) * frac)])
    full = read_dataflash(src)
    try:
        rec = read_dataflash(cut)
    except InputError:
        return  # nothing usable left: a one-line error is the right answer
    if rec.baro is not None:
        assert rec.baro.t_us.size <= full.baro.t_us.size
        np.testing.assert_array_equal(rec.baro.t_us, full.baro.t_us[: rec.baro.t_us.size])
    list(OnboardSource(cut, record=rec))


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_bit_flips_give_a_report_never_a_traceback(tmp_path, seed):
    src = FLIGHTLOGS / "dkla_log171.bin"
    data = bytearray(src.read_bytes())
    rng = np.random.default_rng(seed)
    for pos in rng.integers(2000, len(data), 40):
        data[pos] ^= 1 << int(rng.integers(0, 8))
    bad = tmp_path / "flipped.bin"
    bad.write_bytes(bytes(data))
    try:
        rec = read_dataflash(bad)
    except InputError:
        return
    out = list(OnboardSource(bad, record=rec))
    assert any(isinstance(s, BaroHeight) for s in out)
    for s in out:
        for v in (getattr(s, "height_ref_m", 0.0), getattr(s, "f_up_mps2", 0.0)):
            assert math.isfinite(v)


def test_not_a_log(tmp_path):
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\xa3\x95\x80" + bytes(10))
    with pytest.raises(InputError, match="junk.bin: DataFlash log with nothing mavnav can use"):
        list(open_log(junk))
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.bin"):
        open_log(empty)


def test_gnss_fixes_only_and_reference_home():
    src = open_log(FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN")
    out = list(src)
    g = [s for s in out if isinstance(s, GnssHeight)]
    assert all(s.fix_type >= 3 for s in g)
    ref = src.stats.references["gnss"]
    assert ref.origin == "home" and g[0].height_ref_m == pytest.approx(g[0].alt_m - ref.value)
    assert src.stats.autopilot_reference == "gnss_reference"
