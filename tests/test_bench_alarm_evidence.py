"""bench/alarm_evidence.py: the baro set against the receiver's Doppler
integral, the yardstick neither the baro nor the GNSS altitude enters (the
autopilot's height follows the baro on ArduPilot logs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench import alarm_evidence as ae


def test_a_baro_that_departs_from_the_doppler_integral_reads_its_change():
    t = np.arange(0.0, 100.0, 0.2)
    baro = np.where(t >= 50.0, 2.0, 0.0) + 0.05 * np.sin(t)  # a 2 m step at 50 s
    dop = np.zeros_like(t)  # the vehicle holds its height
    seg = np.zeros_like(t)
    near, usual = ae.departure_within(t, baro - dop, seg, 55.0, 10.0)
    assert near == pytest.approx(2.0, abs=0.15)
    assert usual < 0.15
    assert ae.judge("baro_ins", "baro stepped +2.00 m", (near, usual), (0.1, 0.1), 3.0, 1.0) == "yes"


def test_no_change_spans_a_restart_of_the_integral():
    """Across a gap the integral starts again at an unknown level: a jump of
    the yardstick there is no departure of the baro."""
    t = np.arange(0.0, 100.0, 0.2)
    baro = np.zeros_like(t)
    seg = (t >= 50.0).astype(float)
    dop = np.where(seg > 0, -30.0, 0.0)  # the second segment's own origin
    near, usual = ae.departure_within(t, baro - dop, seg, 52.0, 10.0)
    assert near == pytest.approx(0.0, abs=1e-9)
    assert usual == pytest.approx(0.0, abs=1e-9)
    # read as one series, the restart is a 30 m change
    assert ae.departure(t, baro - dop, 52.0, 10.0)[0] == pytest.approx(30.0)


def test_without_samples_near_the_alarm_there_is_no_reading():
    t = np.arange(0.0, 20.0, 0.2)
    near, usual = ae.departure_within(t, np.zeros_like(t), np.zeros_like(t), 80.0, 10.0)
    assert math.isnan(near) and usual == 0.0
