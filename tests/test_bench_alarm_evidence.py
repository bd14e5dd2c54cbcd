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


def test_a_baro_the_autopilot_follows_departs_only_against_the_doppler():
    """On an ArduPilot log the autopilot's height follows the baro: a baro
    that steps 2 m shows nothing against it, and is seen against the Doppler
    integral (the GNSS altitude, following the Doppler, does not depart)."""
    t = np.arange(0.0, 100.0, 0.2)
    true_m = 0.5 * np.sin(0.1 * t)
    baro = true_m + np.where(t >= 50.0, 2.0, 0.0)
    a = np.column_stack([t, baro, true_m + 0.05 * np.cos(t), baro + 0.01])  # t, baro, GNSS, autopilot
    seg = np.zeros_like(t)
    no_doppler = np.full_like(t, math.nan)
    assert ae.evidence_at("baro_ins", "baro stepped", 55.0, a, no_doppler, seg, 10.0, ae.FACTOR, ae.MIN_M)[3] == "no"
    blamed, other, vs_dop, verdict = ae.evidence_at("baro_ins", "baro stepped", 55.0, a, true_m.copy(), seg, 10.0,
                                                    ae.FACTOR, ae.MIN_M)
    assert verdict == "yes (Doppler)"
    assert vs_dop[0] == pytest.approx(2.0, abs=0.1)
    # an INS alarm is read from its reason, whatever the heights do
    assert ae.evidence_at("baro_ins", "INS velocity changed +2 m/s", 55.0, a, true_m.copy(), seg, 10.0,
                          ae.FACTOR, ae.MIN_M)[3] == "INS"
