"""Clocks, ordering and references: reboot, duplicates, out-of-order, gaps,
Unix GNSS time, untimed messages, vehicle selection, reference origins."""

from __future__ import annotations

import pytest

from mavnav.atmosphere import pressure_at_height_pa
from mavnav.samples import (
    AutopilotHeight, BaroHeight, Gap, GnssHeight, LinkLost, LinkRecovered, RangeHeight, Reboot, ReferenceSet,
    SpecificForceUp,
)
from tests.support.flightlog import (
    MAV_AUTOPILOT_ARDUPILOTMEGA, P_GROUND_PA, UNIX0, FlightLog, collect, of, rejected,
)

MEASUREMENTS = (SpecificForceUp, BaroHeight, GnssHeight, RangeHeight, AutopilotHeight)


def assert_strictly_increasing_per_kind_and_boot(items):
    last = {}
    for s in items:
        if isinstance(s, MEASUREMENTS):
            key = (type(s), s.boot)
            assert s.t_us > last.get(key, -1), (s, last.get(key))
            last[key] = s.t_us


def test_reboot_is_reported_and_boot_increments(tmp_path):
    f = FlightLog(tmp_path / "reboot.tlog", boot0_s=100.0)
    f.fly(0, 4, height_fn=lambda t: t)
    f.boot0_s = 3.0 - 10.0  # after the reboot vehicle time restarts near 3 s
    f.fly(10, 14, height_fn=lambda t: 2.0)
    items, st = collect(f.close())
    reboots = of(items, Reboot)
    assert len(reboots) == 1 and st.reboots == 1
    rb = reboots[0]
    assert rb.boot == 1 and rb.last_t_us == pytest.approx(103.99e6, abs=0.02e6) and rb.t_us == 3_000_000
    idx = items.index(rb)
    for cls in (SpecificForceUp, BaroHeight, GnssHeight):
        before = [s for s in items[:idx] if isinstance(s, cls)]
        after = [s for s in items[idx:] if isinstance(s, cls)]
        assert before and after
        assert {s.boot for s in before} == {0} and {s.boot for s in after} == {1}
    assert not rejected(items, "out_of_order")  # nothing lost at the boundary
    assert st.samples["imu"] == 800 and st.samples["baro"] == 160
    assert_strictly_increasing_per_kind_and_boot(items)
    assert st.duration_s == pytest.approx(8.0, abs=0.1)


def test_single_corrupt_time_is_not_a_reboot(tmp_path):
    f = FlightLog(tmp_path / "jump.tlog", boot0_s=100.0)
    f.fly(0, 2)
    f.pressure(2.0, P_GROUND_PA, t_ms=5_000)  # one wild time value, CRC-valid
    f.fly(2.01, 4)
    items, st = collect(f.close())
    assert st.reboots == 0 and not of(items, Reboot)
    assert st.rejected["stale"] == 1  # behind the clock and alone: dropped as a stale packet


def test_duplicates_and_out_of_order_are_dropped_and_counted(tmp_path):
    f = FlightLog(tmp_path / "dup.tlog")
    f.heartbeat(0)
    f.attitude(0.0)
    for t in (0.1, 0.2, 0.2, 0.3, 0.25, 0.4):
        f.pressure(t, P_GROUND_PA)
        f.highres(t)
        f.attitude(t + 0.001)
    f.attitude(0.6)
    items, st = collect(f.close(), baro_reference={"source": "config", "value": P_GROUND_PA})
    assert [b.t_us for b in of(items, BaroHeight)] == [f.us(t) for t in (0.1, 0.2, 0.3, 0.4)]
    assert [s.t_us for s in of(items, SpecificForceUp)] == [f.us(t) for t in (0.1, 0.2, 0.3, 0.4)]
    assert st.rejected["duplicate"] == 2 and st.rejected["out_of_order"] == 2
    assert st.samples["baro"] == 4


def test_gap_is_reported_with_its_length(tmp_path):
    f = FlightLog(tmp_path / "gap.tlog")
    f.fly(0, 3)
    f.fly(3, 6, baro_hz=0)  # barometer silent for 3 s
    f.fly(6, 8)
    items, st = collect(f.close())
    gaps = [g for g in of(items, Gap) if g.kind == "baro"]
    assert len(gaps) == 1
    assert gaps[0].length_s == pytest.approx(3.05, abs=0.01) and gaps[0].t_us == f.us(6.0)
    assert not [g for g in of(items, Gap) if g.kind == "imu"]
    # the gap comes right before the first sample after it
    i = items.index(gaps[0])
    assert isinstance(items[i + 1], BaroHeight) and items[i + 1].t_us == gaps[0].t_us
    assert st.gaps[0].kind == "baro"


def test_gnss_unix_time_is_mapped_to_boot_time(tmp_path):
    f = FlightLog(tmp_path / "unix.tlog", boot0_s=50.0)
    unix_at_boot_us = 1_600_000_000_000_000
    f.heartbeat(0)
    f.attitude(0.0)
    f.system_time(0.0, unix_at_boot_us + f.us(0.0))
    for k in range(5):
        f.attitude(0.2 * k + 0.1)
        f.gps(0.2 * k + 0.1, 500.0, time_usec=unix_at_boot_us + f.us(0.2 * k + 0.05))
    items, _ = collect(f.close())
    gs = of(items, GnssHeight)
    assert [g.t_us for g in gs] == [f.us(0.2 * k + 0.05) for k in range(5)]


def test_gnss_unix_time_without_system_time_uses_receive_offset(tmp_path):
    f = FlightLog(tmp_path / "unix2.tlog", boot0_s=50.0)
    f.heartbeat(0)
    for k in range(5):
        f.attitude(0.2 * k)
        # receive clock == Unix time here; the fix time is 50 ms before reception
        f.gps(0.2 * k + 0.01, 500.0, time_usec=int(round((f.recv(0.2 * k + 0.01) - 0.05) * 1e6)))
    gs = of(collect(f.close())[0], GnssHeight)
    assert len(gs) == 5
    for k, g in enumerate(gs):
        assert g.t_us == pytest.approx(f.us(0.2 * k + 0.01) - 50_000, abs=2_000)


def test_rangefinder_gets_vehicle_time_from_receive_offset(tmp_path):
    f = FlightLog(tmp_path / "rf.tlog", autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA, boot0_s=20.0)
    f.heartbeat(0)
    for k in range(5):
        f.attitude(0.1 * k)
        f.latency_s = 0.005 + 0.03  # RANGEFINDER arrives 30 ms after the attitude
        f.rangefinder(0.1 * k, 4.0)
        f.latency_s = 0.005
    rs = of(collect(f.close())[0], RangeHeight)
    assert [r.t_us for r in rs] == [f.us(0.1 * k) + 30_000 for k in range(5)]


def test_ground_station_and_other_vehicles_are_ignored(tmp_path):
    f = FlightLog(tmp_path / "multi.tlog")
    f.heartbeat(0.0, mav_type=6, autopilot=8, sysid=255, compid=190)  # a GCS first
    f.pressure(0.0, 50_000.0, sysid=255, compid=190)
    f.heartbeat(0.001, sysid=1)  # the vehicle
    for k in range(10):
        t = 0.1 * k + 0.01
        f.pressure(t, P_GROUND_PA)
        f.pressure(t + 0.001, 80_000.0, sysid=2)  # another vehicle on the same link
        f.heartbeat(t + 0.002, sysid=2)
        f.pressure(t + 0.003, 70_000.0, sysid=255, compid=190)
    items, st = collect(f.close(), baro_reference={"source": "config", "value": P_GROUND_PA})
    bs = of(items, BaroHeight)
    assert len(bs) == 10 and all(b.pressure_pa == pytest.approx(P_GROUND_PA) for b in bs)
    assert st.vehicle.sysid == 1 and st.vehicle.mav_type == 2
    assert st.ignored_by_sysid[2] == 20 and st.ignored_by_sysid[255] == 12
    # an explicit sysid picks the other vehicle
    items, st = collect(f.path, sysid=2, baro_reference={"source": "config", "value": P_GROUND_PA})
    assert [b.pressure_pa for b in of(items, BaroHeight)] == pytest.approx([80_000.0] * 10)


def test_samples_before_the_first_heartbeat_are_kept(tmp_path):
    f = FlightLog(tmp_path / "late_hb.tlog")
    for k in range(5):
        f.pressure(0.1 * k, P_GROUND_PA)
    f.heartbeat(0.6)
    items, st = collect(f.close(), baro_reference={"source": "config", "value": P_GROUND_PA})
    assert len(of(items, BaroHeight)) == 5


def test_startup_references_hold_samples_and_lose_none(tmp_path):
    f = FlightLog(tmp_path / "startup.tlog")
    f.fly(0, 6, height_fn=lambda t: 0.0 if t < 3 else 5.0)
    items, st = collect(f.close())
    refs = of(items, ReferenceSet)
    assert {r.kind: r.origin for r in refs} == {"baro": "startup", "gnss": "startup"}
    baro_ref = next(r for r in refs if r.kind == "baro")
    assert baro_ref.value == pytest.approx(P_GROUND_PA, rel=1e-6)
    gnss_ref = next(r for r in refs if r.kind == "gnss")
    assert gnss_ref.value == pytest.approx(500.0) and gnss_ref.alt_ref_msl_m == pytest.approx(500.0)
    bs = of(items, BaroHeight)
    assert len(bs) == 120 and bs[0].t_us == f.us(0.0)  # none lost while the window filled
    assert items.index(baro_ref) < items.index(bs[0])
    assert bs[-1].height_ref_m == pytest.approx(5.0, abs=0.05)
    assert of(items, GnssHeight)[-1].height_ref_m == pytest.approx(5.0)


def test_samples_wait_with_the_baro_for_its_reference_and_none_is_lost(tmp_path):
    """A link without a home (a real ArduPilot tlog, mrr_iarc2018_flight_8b2c,
    held its baro 20 s waiting for one): the IMU and the rangefinder wait with
    the baro and come out with it in time order, after the reference, so the
    epoch builder meets them after its start. Before, they went ahead, and the
    builder, not yet started, dropped all 55 rangefinder readings of that
    flight and all but the last IMU sample."""
    from mavnav.config import config_from_dict
    from mavnav.epochs import EpochBuilder

    f = FlightLog(tmp_path / "nohome.tlog")
    f.fly(0, 8, height_fn=lambda t: 2.0, gps_hz=0, range_hz=10)
    items, st = collect(f.close(), baro_reference={"source": "home", "home_wait_s": 30.0})
    ref = next(r for r in of(items, ReferenceSet) if r.kind == "baro")
    assert ref.origin == "startup"
    first_baro = items.index(of(items, BaroHeight)[0])
    assert items.index(ref) < first_baro
    # in time order per boot, every kind together
    timed = [s for s in items if isinstance(s, MEASUREMENTS)]
    assert [s.t_us for s in timed] == sorted(s.t_us for s in timed)
    b = EpochBuilder(config_from_dict({}))
    for s in items:
        b.push(s)
    # (the reading at the very first instant, beside the first baro sample, is before the start)
    assert b.counters["rng_before_start"] <= 1
    assert b.counters["rng_used"] >= 0.95 * b.counters["rng_in"] > 0


def test_home_references(tmp_path):
    f = FlightLog(tmp_path / "home.tlog")
    f.fly(0, 3, height_fn=lambda t: 0.0, ground_msl_m=480.0)
    f.home(3.0, 480.0)
    f.fly(3, 8, height_fn=lambda t: 10.0, ground_msl_m=480.0)
    cfg = {"baro_reference": {"source": "home"}, "gnss_reference": {"source": "home"}}
    items, st = collect(f.close(), **cfg)
    refs = {r.kind: r for r in of(items, ReferenceSet)}
    assert refs["baro"].origin == "home" and refs["baro"].alt_ref_msl_m == pytest.approx(480.0)
    assert refs["baro"].value == pytest.approx(P_GROUND_PA, rel=1e-6)
    assert refs["gnss"].origin == "home" and refs["gnss"].value == pytest.approx(480.0)
    assert of(items, GnssHeight)[-1].height_ref_m == pytest.approx(10.0)
    assert len(of(items, BaroHeight)) == 160


def test_late_home_corrects_baro_reference_with_relative_alt(tmp_path):
    # HOME_POSITION first seen mid-flight, at 20 m above home
    f = FlightLog(tmp_path / "late_home.tlog")
    f.heartbeat(0)
    for k in range(40):
        t = 0.1 * k
        f.gpi(t, 520.0, rel_m=20.0)
        f.pressure(t + 0.01, pressure_at_height_pa(20.0, P_GROUND_PA))
    f.home(4.0, 500.0)
    for k in range(40, 70):
        f.pressure(0.1 * k, pressure_at_height_pa(20.0, P_GROUND_PA))
    items, st = collect(f.close(), baro_reference={"source": "home"})
    # the home in GLOBAL_POSITION_INT (alt - relative_alt) fixes it before HOME_POSITION comes
    assert st.references["baro"].origin == "autopilot_home"
    assert st.references["baro"].alt_ref_msl_m == pytest.approx(500.0)
    assert st.references["baro"].value == pytest.approx(P_GROUND_PA, rel=2e-5)
    assert of(items, BaroHeight)[0].height_ref_m == pytest.approx(20.0, abs=0.1)


def test_home_never_sent_falls_back_to_startup(tmp_path):
    f = FlightLog(tmp_path / "nohome.tlog")
    f.fly(0, 4)
    items, st = collect(f.close(), baro_reference={"source": "home", "home_wait_s": 1.5})
    assert st.references["baro"].origin == "startup"
    assert len(of(items, BaroHeight)) == 80


def test_stuck_rangefinder_is_flagged_when_baro_moves(tmp_path):
    g = FlightLog(tmp_path / "stuck2.tlog")
    for k in range(600):
        t = k / 100.0
        if k % 100 == 0:
            g.heartbeat(t)
        if k % 2 == 0:
            g.attitude(t)
        if k % 5 == 0:
            g.pressure(t, pressure_at_height_pa(2.0 + t, P_GROUND_PA))  # climbing 1 m/s
        if k % 10 == 0:
            g.dist(t, 3.0)  # but the rangefinder reads 3.00 m all along
    items, st = collect(g.close(), rangefinder_stuck_s=2.0)
    stuck = rejected(items, "stuck")
    rs = of(items, RangeHeight)
    assert stuck and all(s.t_us >= g.us(2.0) for s in stuck)
    assert len(rs) + len(stuck) == 60 and len(rs) <= 21
    # hovering (baro steady), the same steady reading is fine
    h = FlightLog(tmp_path / "hover.tlog")
    h.fly(0, 6, height_fn=lambda t: 3.0)
    items, st = collect(h.close(), rangefinder_stuck_s=2.0)
    assert not rejected(items, "stuck") and len(of(items, RangeHeight)) == 60


def test_receive_hole_in_a_tlog_is_link_loss_and_recovery(tmp_path):
    f = FlightLog(tmp_path / "hole.tlog")
    f.fly(0, 2)
    f.latency_s = 5.0  # the next messages reached the ground 5 s late: silence on the link
    f.fly(2, 3)
    items, st = collect(f.close(), link_timeout_s=2.0)
    lost, rec = of(items, LinkLost), of(items, LinkRecovered)
    assert len(lost) == 1 and len(rec) == 1 and st.link_losses == 1
    assert rec[0].outage_s == pytest.approx(5.0, abs=0.02)
    assert lost[0].recv_s == pytest.approx(UNIX0 + 1.99 + 0.005 + 2.0, abs=0.02)
