"""--inject: faults applied to normalised samples of any source change only the
faulted source, only inside the window, with the semantics of `mavnav inject`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mavnav.atmosphere import height_from_pressure_m
from mavnav.cli import main
from mavnav.ingest import open_log
from mavnav.samples import (
    BaroHeight,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    RangeHeight,
    Reboot,
    Rejected,
    SpecificForceUp,
)
from mavnav.sim.effects import SampleFaults, height_error_m, keeps
from mavnav.sim.faults import parse_fault
from tests.support.paths import SHARED_FLIGHTLOGS

FLIGHTLOGS = SHARED_FLIGHTLOGS
BIN = FLIGHTLOGS / "SITL_wlichon_baseline_00000001.BIN"
pytestmark = [pytest.mark.realdata, pytest.mark.slow, pytest.mark.skipif(not BIN.exists(), reason=f"{BIN} not present")]


@pytest.fixture(scope="module")
def base():
    return list(open_log(BIN))


def _apply(samples, spec):
    return list(SampleFaults([parse_fault(spec)]).apply(samples))


def _pairs(a, b, cls):
    xa = [s for s in a if isinstance(s, cls)]
    xb = [s for s in b if isinstance(s, cls)]
    return xa, xb


@pytest.mark.parametrize("spec,cls,field", [
    ("gnss_step:onset=60,duration=10,magnitude=10", GnssHeight, "height_ref_m"),
    ("gnss_ramp:onset=60,duration=10,magnitude=0.5", GnssHeight, "height_ref_m"),
    ("baro_step:onset=60,duration=10,magnitude=5", BaroHeight, "height_ref_m"),
    ("baro_ramp:onset=60,duration=10,magnitude=0.5", BaroHeight, "height_ref_m"),
    ("accel_bias_step:onset=60,duration=10,magnitude=0.5", SpecificForceUp, "f_up_mps2"),
])
def test_only_the_faulted_source_changes_inside_its_window(base, spec, cls, field):
    fault = parse_fault(spec)
    out = _apply(base, spec)
    assert len(out) == len(base)
    changed_types = {type(a) for a, b in zip(base, out) if a != b}
    assert changed_types == {cls}
    xa, xb = _pairs(base, out, cls)
    for a, b in zip(xa, xb):
        t = a.t_us * 1e-6
        d = getattr(b, field) - getattr(a, field)
        if fault.onset_s <= t < fault.end_s:
            assert d == pytest.approx(height_error_m(fault, t))
        else:
            assert d == 0.0


def test_baro_pressure_moves_with_the_height(base):
    out = _apply(base, "baro_step:onset=60,duration=10,magnitude=5")
    xa, xb = _pairs(base, out, BaroHeight)
    p_ref = None
    for a, b in zip(xa, xb):
        if b.height_ref_m != a.height_ref_m:
            # the same reference pressure explains both the old and the new height
            p_ref = a.pressure_pa / (1 - a.height_ref_m * 0.0065 / 288.15) ** (9.80665 / (287.05287 * 0.0065))
            assert height_from_pressure_m(b.pressure_pa, p_ref) == pytest.approx(b.height_ref_m, abs=1e-6)
    assert p_ref is not None


def test_frozen_baro_repeats_the_last_value_before_onset(base):
    out = _apply(base, "baro_freeze:onset=60,duration=5")
    xa, xb = _pairs(base, out, BaroHeight)
    before = [a for a in xa if a.t_us * 1e-6 < 60][-1]
    inside = [b for b in xb if 60 <= b.t_us * 1e-6 < 65]
    assert inside and all(b.pressure_pa == before.pressure_pa for b in inside)


def test_gnss_dropout_removes_samples_and_rate_drop_keeps_one_in_n(base):
    out = _apply(base, "gnss_dropout:onset=60,duration=10")
    g0 = [s for s in base if isinstance(s, GnssHeight) and 60 <= s.t_us * 1e-6 < 70]
    g1 = [s for s in out if isinstance(s, GnssHeight) and 60 <= s.t_us * 1e-6 < 70]
    assert g0 and not g1
    out = _apply(base, "rate_drop:onset=60,duration=10,magnitude=0.25")
    b0 = [s for s in base if isinstance(s, BaroHeight) and 60 <= s.t_us * 1e-6 < 70]
    b1 = [s for s in out if isinstance(s, BaroHeight) and 60 <= s.t_us * 1e-6 < 70]
    assert b1 == [s for i, s in enumerate(b0) if keeps(parse_fault("rate_drop:onset=0,magnitude=0.25"), i)]


def _with_range(samples):
    """A valid downward rangefinder beside the log's samples (this SITL log's own reads 0)."""
    out = []
    for s in samples:
        out.append(s)
        if isinstance(s, BaroHeight):
            h = max(0.5, s.height_ref_m + 1.0)
            out.append(RangeHeight(s.t_us + 1, s.recv_s, s.boot, h * 0.99, h, "RFND[0]", 0.2, 40.0))
    return out


def test_rangefinder_faults_become_the_refusals_a_source_would_make(base):
    rng = _with_range(base)
    out = _apply(rng, "rng_stuck:onset=60,duration=10,magnitude=0")
    new = [s for s in out if isinstance(s, Rejected) and s.kind == "out_of_range"]
    window = [s for s in rng if isinstance(s, RangeHeight) and 60 <= s.t_us * 1e-6 < 70]
    assert len(new) == len(window) > 0 and all(r.sensor == "range" for r in new)
    assert [r.t_us for r in new] == [s.t_us for s in window]
    out = _apply(rng, "rng_stuck:onset=60,duration=10")
    r0 = [s for s in rng if isinstance(s, RangeHeight) and s.t_us * 1e-6 < 60][-1]
    inside = [s for s in out if isinstance(s, RangeHeight) and 60 <= s.t_us * 1e-6 < 70]
    assert inside and all(s.range_m == r0.range_m for s in inside)
    out = _apply(rng, "rng_out_of_range:onset=60,duration=10")
    assert all(not (isinstance(s, RangeHeight) and 60 <= s.t_us * 1e-6 < 70) for s in out)


def test_link_loss_and_reboot_events(base):
    out = _apply(base, "link_loss:onset=60,duration=5")
    lost = [s for s in out if isinstance(s, LinkLost)]
    back = [s for s in out if isinstance(s, LinkRecovered)]
    assert len(lost) == 1 and len(back) == 1 and back[0].outage_s == pytest.approx(5.0)
    assert not [s for s in out if getattr(s, "t_us", None) and 60 <= s.t_us * 1e-6 < 65]
    out = _apply(base, "reboot:onset=60,duration=5")
    rb = [s for s in out if isinstance(s, Reboot)]
    assert len(rb) == 1 and rb[0].boot == 1
    after = [s for s in out if isinstance(s, BaroHeight) and s.boot == 1]
    assert after and after[0].t_us < 10e6  # vehicle time restarted


def test_cli_inject_on_a_dataflash_log_alarms_the_gnss_step(tmp_path):
    out = tmp_path / "a.json"
    res = CliRunner().invoke(main, ["audit", str(BIN), "--inject", "gnss_step:onset=75,duration=10,magnitude=10",
                                    "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())["files"][0]
    assert doc["format"] == "dataflash"
    inj = doc["injected"][0]
    assert inj["kind"] == "gnss_step" and inj["samples_modified"] == 50  # 10 s of 5 Hz GNSS
    # this log's rangefinder reads 0 m all flight (a real dead sensor, alarmed on
    # its own); the injected step is the only other alarm, on the GNSS, in time
    others = [a for a in doc["alarms"] if a["state"] == "alarm" and a["source"] != "rangefinder"]
    assert others and others[0]["source"] == "gnss" and 75 <= others[0]["t_s"] < 76
    assert all(a["source"] == "gnss" for a in others)
    clean = CliRunner().invoke(main, ["audit", str(BIN), "--json", str(tmp_path / "c.json")])
    assert clean.exit_code == 0
    doc = json.loads((tmp_path / "c.json").read_text())["files"][0]
    assert {a["source"] for a in doc["alarms"] if a["state"] == "alarm"} == {"rangefinder"}


def test_cli_refuses_a_bad_fault_before_work():
    res = CliRunner().invoke(main, ["replay", str(BIN), "--inject", "gnss_step:onset=1"])
    assert res.exit_code == 2 and "needs a magnitude" in res.output
