"""Start-up and mid-flight connect: the height reference comes from what the
autopilot already streams (GLOBAL_POSITION_INT alt - relative_alt, HOME_POSITION,
GPS_GLOBAL_ORIGIN with LOCAL_POSITION_NED) within about a second, on the ground or
in the air; with none of it the start-up mean, said on the console, after at most
the configured wait. Recorded flights and a real UDP link on 127.0.0.1."""

from __future__ import annotations

import math
import threading
import time

import pytest

from mavnav.atmosphere import pressure_at_height_pa
from mavnav.cli.run import AlarmPrinter
from mavnav.config import Config, IngestConfig
from mavnav.ingest import LiveSource
from mavnav.pipeline import run
from mavnav.samples import AutopilotHeight, BaroHeight, GnssHeight, ReferenceSet
from mavnav.sinks.base import Sink
from tests.support.live import Sender, tlog_records
from tests.support.flightlog import P_GROUND_PA, UNIX0, FlightLog, collect, of
from tests.support.paths import SITL_LOGS

HOME_MSL_M = 480.0
UP_M = 14.0  # connected 14 m above home


def hover(t):
    """14 m up, a gentle 0.2 m sway (a constant pressure would be a resent value, no epoch)."""
    return UP_M + 0.2 * math.sin(1.3 * t)


def midflight(path, *, gpi=True, home_at=None, lpn_origin=False, seconds=40.0, height=hover):
    """A vehicle already in the air when the recording (or the link) starts."""
    f = FlightLog(path)
    k = 0
    while k * 0.25 < seconds:
        t = k * 0.25
        f.fly(t, t + 0.25, height_fn=height, ground_msl_m=HOME_MSL_M, range_hz=0)
        h = height(t + 0.24)
        if home_at is not None and abs(t - home_at) < 1e-9:
            f.home(t + 0.24, HOME_MSL_M)
        if gpi:
            f.gpi(t + 0.24, HOME_MSL_M + h, rel_m=h)
        if lpn_origin:
            f.lpn(t + 0.24, -h)
            if k % 4 == 0:
                f.put(f.mav.gps_global_origin_encode(473977000, 85455000, int(HOME_MSL_M * 1000)), t + 0.24)
        k += 1
    return f.close()


class Epochs(Sink):
    name = "epochs"

    def __init__(self):
        self.rows = []
        self.alarms = []

    def epoch(self, r):
        self.rows.append(r)

    def alarm(self, ev):
        self.alarms.append(ev)


@pytest.mark.parametrize("how", ["gpi", "lpn_origin", "home"])
def test_midflight_connect_references_within_a_second(tmp_path, how):
    path = midflight(tmp_path / "mid.tlog", gpi=how != "lpn_origin", lpn_origin=how == "lpn_origin",
                     home_at=0.0 if how == "home" else None, seconds=6.0)
    items, st = collect(path)
    refs = {r.kind: r for r in of(items, ReferenceSet)}
    want = {"gpi": "autopilot_home", "lpn_origin": "ekf_origin", "home": "home"}[how]
    assert refs["baro"].origin == want and refs["gnss"].origin == want
    assert refs["gnss"].value == pytest.approx(HOME_MSL_M) and refs["baro"].alt_ref_msl_m == pytest.approx(HOME_MSL_M)
    bs, gs = of(items, BaroHeight), of(items, GnssHeight)
    # heights above home from the first sample: not zero at the connect height
    assert bs[0].t_us == 5_000_000 and bs[0].height_ref_m == pytest.approx(hover(0.0), abs=0.05)
    assert gs[0].height_ref_m == pytest.approx(hover(0.0), abs=0.01)
    assert refs["baro"].value == pytest.approx(P_GROUND_PA, rel=1e-5)
    # known within about a second of connecting (receive time of the stream)
    for r in refs.values():
        assert r.recv_s - (UNIX0 + 0.005) <= 1.3, r
    assert st.autopilot_reference == "gnss_reference"
    assert [a.height_ref_m for a in of(items, AutopilotHeight)][:3] == pytest.approx([UP_M] * 3, abs=0.25)


def test_climbing_connect_moves_the_pairing_along_the_vertical_speed(tmp_path):
    # climbing 3 m/s: a baro sample 0.24 s before the GLOBAL_POSITION_INT it pairs with
    # is 0.72 m lower; vz carries it there
    f = FlightLog(tmp_path / "climb.tlog")
    h = lambda t: 10.0 + 3.0 * t  # noqa: E731
    k = 0
    while k * 0.25 < 4.0:
        t = k * 0.25
        f.fly(t, t + 0.25, height_fn=h, ground_msl_m=HOME_MSL_M, range_hz=0)
        t1 = t + 0.24
        f.put(f.mav.global_position_int_encode(f.ms(t1), 473977000, 85455000, int(round((HOME_MSL_M + h(t1)) * 1000)),
                                               int(round(h(t1) * 1000)), 0, 0, -300, 0), t1)
        k += 1
    items, st = collect(f.close())
    assert st.references["baro"].value == pytest.approx(P_GROUND_PA, rel=3e-6)  # 0.25 m of pressure
    assert of(items, BaroHeight)[0].height_ref_m == pytest.approx(10.0, abs=0.25)


def test_arducopter_before_home_is_set_is_not_a_home(tmp_path):
    # old ArduCopter, position known but home not yet set: relative_alt == alt (home at 0 m)
    f = FlightLog(tmp_path / "nohome.tlog")
    for k in range(24):
        t = k * 0.25
        f.fly(t, t + 0.25, ground_msl_m=HOME_MSL_M, range_hz=0)
        f.gpi(t + 0.24, HOME_MSL_M, rel_m=HOME_MSL_M)
    items, st = collect(f.close(), baro_reference={"source": "home", "home_wait_s": 3.0},
                        gnss_reference={"source": "home", "home_wait_s": 3.0})
    assert {k: r.origin for k, r in st.references.items()} == {"baro": "startup", "gnss": "startup"}
    assert st.references["gnss"].value == pytest.approx(HOME_MSL_M)


def test_midflight_connect_gives_no_false_gnss_alarm(tmp_path):
    """The issue's case: connected 14 m up, the reference used to be taken there after
    30 s (baro 0, GNSS 10 m: a false GNSS alarm to landing)."""
    path = midflight(tmp_path / "mid.tlog", seconds=40.0)
    cfg = Config()
    from mavnav.ingest import TlogSource

    sink = Epochs()
    summary = run(TlogSource(path, cfg.ingest), cfg, [sink])
    assert summary.epochs > 500
    assert not [a for a in sink.alarms if a.source in ("gnss", "baro_ins") and a.state in ("caution", "alarm")]
    late = [r for r in sink.rows if r.t_us > 10_000_000]
    assert all(abs(r.height_fused_m - UP_M) < 1.0 for r in late if r.height_fused_m == r.height_fused_m)
    assert sum(1 for r in late if r.height_fused_m == r.height_fused_m) > 0.9 * len(late)


def test_startup_fallback_is_said_and_bounded(tmp_path, capsys):
    # no autopilot position at all: the start-up mean, after at most the wait, and the console says why
    from mavnav.samples import Notice

    path = midflight(tmp_path / "nogpi.tlog", gpi=False, seconds=6.0, height=lambda t: 0.2 * math.sin(t))
    items, st = collect(path, baro_reference={"source": "home", "home_wait_s": 2.5},
                        gnss_reference={"source": "home", "home_wait_s": 2.5})
    notes = [n for n in of(items, Notice) if n.kind != "vehicle"]
    assert {n.kind for n in notes} == {"waiting_reference"} and len(notes) == 2
    assert "waiting for HOME_POSITION or GLOBAL_POSITION_INT to fix the baro height reference" in notes[0].text
    refs = {r.kind: r for r in of(items, ReferenceSet)}
    assert refs["baro"].origin == "startup" and refs["gnss"].origin == "startup"
    bs = of(items, BaroHeight)
    # said after a second of waiting, released after at most the wait: nothing held longer
    assert notes[0].recv_s - bs[0].recv_s == pytest.approx(1.0, abs=0.1)
    assert refs["baro"].recv_s - bs[0].recv_s <= 2.5 + 0.06
    assert len(bs) == 120
    AlarmPrinter().sample(notes[0])
    AlarmPrinter().sample(refs["baro"])
    err = capsys.readouterr().err
    assert "waiting for HOME_POSITION or GLOBAL_POSITION_INT to fix the baro height reference" in err
    assert "start-up" in err


@pytest.mark.integration
@pytest.mark.slow
def test_live_midflight_connect_over_udp(tmp_path, capsys):
    """Real UDP on 127.0.0.1 at 4x: the first epochs already say 14 m, and nothing
    waits for HOME_POSITION (no 'waiting' line on the console)."""
    path = midflight(tmp_path / "mid.tlog", seconds=12.0)
    src = LiveSource("udpin:127.0.0.1:0", IngestConfig(link_timeout_s=5.0))
    sender = Sender(tlog_records(path), src.local_address, speed=4.0)
    sink = Epochs()
    t_start = time.monotonic()
    first_epoch_wall = {}

    class FirstEpoch(Sink):
        name = "first"

        def epoch(self, r):
            first_epoch_wall.setdefault("t", time.monotonic())

    def stop_later():
        sender.join()
        time.sleep(0.5)
        src.close()

    sender.start()
    threading.Thread(target=stop_later, daemon=True).start()
    cfg = Config()
    run(src, cfg, [AlarmPrinter(), sink, FirstEpoch()], info={"live": True})
    err = capsys.readouterr().err
    assert "waiting for HOME_POSITION" not in err
    assert "height reference" in err and "GLOBAL_POSITION_INT" in err
    # the first epoch came within about a second of vehicle time (0.25 s of wall time at 4x)
    assert first_epoch_wall["t"] - t_start < 1.5
    fused = [r.height_fused_m for r in sink.rows if r.height_fused_m == r.height_fused_m]
    assert fused and fused[0] == pytest.approx(UP_M, abs=1.5)
    assert [r.baro_height_ref_m for r in sink.rows][0] == pytest.approx(UP_M, abs=0.1)


def test_first_imu_first_so_a_quick_reference_loses_no_epoch():
    """A reference known at once releases the baro before the IMU (held for its source
    choice): measurements wait for the first IMU sample of the boot, then join in time
    order, so the epochs start with the data (ArduPilot SITL connected 30 m up)."""

    from mavnav.ingest import TlogSource
    from mavnav.monitor import Monitor

    cfg = Config()
    mon = Monitor(cfg)
    n = 0
    for s in TlogSource(SITL_LOGS / "ardupilot_rng_dropout.tlog", cfg.ingest):
        n += len(mon.push(s))
    c = mon.builder.counters
    # only what precedes the first IMU sample in vehicle time (one baro, one GNSS, one range)
    assert c["baro_before_imu"] <= 1 and c["gnss_before_start"] <= 1 and c["rng_before_start"] <= 1, dict(c)
    assert c["imu_stale_epochs"] == 0 and n >= 898
