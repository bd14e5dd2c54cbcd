"""The channel a baro sample is judged in (HypothesisLogic._anchor): an aux
channel only while its own sensor holds it, else the baro+INS channel."""

from __future__ import annotations

import pytest

from mavnav.bank import BARO, GNSS
from mavnav.monitor.core import Monitor
from mavnav.samples import GnssHeight, RangeHeight
from tests.support.monitor import T0_US, cfg_for, hover
from tests.support.synthetic import Schedule, paper_flight

QUIET_FROM_S = 40.0  # the GNSS goes quiet here (a receiver lost, a logging gap)


@pytest.mark.simulation
@pytest.mark.parametrize("seed", [1, 2])
def test_a_channel_coasting_without_its_sensor_is_no_anchor(seed):
    sched = Schedule(duration_s=60.0, imu_dt_s=0.01, baro_every=2, gnss_every=20, rng_every=5)
    flight = paper_flight(seed=seed, schedule=sched, accel=hover, h0_m=10.0, t0_us=T0_US)
    quiet_us = T0_US + int(QUIET_FROM_S * 1e6)
    samples = [s for s in flight.samples if not isinstance(s, RangeHeight)
               and not (isinstance(s, GnssHeight) and s.t_us >= quiet_us)]
    mon = Monitor(cfg_for("adaptive"))
    seen = {}
    for s in samples:
        for rep, _ in mon.push(s):
            t_s = (rep.t_us - T0_US) * 1e-6
            for probe in (35.0, 50.0):
                if probe not in seen and t_s >= probe:
                    seen[probe] = mon.logic._anchor(rep.t_us)
    assert seen[35.0] == GNSS  # the GNSS holds its channel best while it reports
    assert seen[50.0] == BARO  # 10 s without a GNSS sample: its channel holds nothing
