"""The baro's robust level at a GNSS sample's time for the baro/Doppler
check: exact on a smooth climb, deaf to one outlier, a ramp's rate passed
whole, a step within half its span; on a real flight with spikes and a ramp
injected into its baro."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavnav.config import config_from_dict
from mavnav.ingest import open_log
from mavnav.monitor.barolevel import BaroLevel
from mavnav.monitor.doppler import DopplerCheck
from mavnav.samples import BaroHeight, GnssHeight
from tests.support.paths import SHARED_FLIGHTLOGS

DKLA = SHARED_FLIGHTLOGS / "dkla_log171.bin"  # ArduCopter 3.3: baro at 11 Hz, GPS with VZ at 5 Hz


def _feed(baro, gnss, span_s=1.0, window_s=10.0):
    """Baro (t_s, h_m) and GNSS (t_s, v_mps) in time order through a level and
    a 10 s baro/Doppler window, as the monitor feeds them: per GNSS sample, its
    time, the level at its end and the window's reading (None while not full).
    ``span_s`` None: the latest baro sample carried by the Doppler velocity at
    both ends, as the check read it before."""
    level = BaroLevel(span_s or 1.0, window_s, 1.5)
    check = DopplerCheck(window_s, 1.5)
    events = sorted([(t, 0, h) for t, h in baro] + [(t, 1, v) for t, v in gnss])
    out = []
    last = None
    for t, kind, x in events:
        t_us = int(round(t * 1e6))
        if kind == 0:
            level.push_baro(t_us, x)
            last = (t, x)
            continue
        level.push_gnss(t_us, x)
        if span_s is None:
            b = None if last is None else last[1] + x * (t - last[0])
            out.append((t, b, None if b is None else check.push(t_us, b, x)))
        else:
            b = level.end_m(t_us)
            out.append((t, b, None if b is None else check.push(t_us, b, x, level.centred_m)))
    return out


@pytest.mark.unit
def test_the_level_of_a_smooth_climb_is_exact_at_the_gnss_time():
    tb = np.arange(0.0, 20.0, 0.1)
    tg = np.arange(0.05, 20.0, 0.2)
    v = lambda t: 1.5 * np.sin(0.4 * t)  # noqa: E731
    h = lambda t: 3.0 + (1.5 / 0.4) * (1.0 - np.cos(0.4 * t))  # noqa: E731
    out = _feed(list(zip(tb, h(tb))), list(zip(tg, v(tg))))
    got = [(t, b) for t, b, _ in out if b is not None]
    assert len(got) > 90
    # samples up to 1 s old, each carried along the Doppler integral: the trapezoid's error only
    assert max(abs(b - h(t)) for t, b in got[5:]) < 0.03
    assert max(abs(e) for _, _, e in out if e is not None) < 0.05


@pytest.mark.unit
def test_one_outlier_moves_neither_end_and_a_ramp_is_read_one_sample_late():
    tb = np.arange(0.0, 30.0, 0.1)
    tg = np.arange(0.05, 30.0, 0.2)
    spike = np.where(np.isclose(tb, 12.0), 3.0, 0.0)
    out = _feed(list(zip(tb, spike)), [(t, 0.0) for t in tg])
    assert max(abs(b) for _, b, _ in out if b is not None) == 0.0  # the median of the last 3
    assert max(abs(e) for _, _, e in out if e is not None) == 0.0  # and of the second about the start
    ramp = np.where(tb >= 15.0, 0.5 * (tb - 15.0), 0.0)
    out = {round(t, 2): (b, e) for t, b, e in _feed(list(zip(tb, ramp)), [(t, 0.0) for t in tg])}
    b, e = out[25.05]
    assert b == pytest.approx(0.5 * (24.9 - 15.0))  # the middle of the last three samples
    # the start's level, centred on 15.05, holds five samples of the ramp's first half second
    assert 0.5 * (24.9 - 15.0) - 0.05 <= e <= 0.5 * (24.9 - 15.0)
    # both ends in the ramp: its rate over the window, less the end's lag (its
    # level is the sample at 29.7, the start's centred on 19.85)
    assert out[29.85][1] == pytest.approx(0.5 * (10.0 - 0.15))


@pytest.mark.unit
def test_a_step_shows_whole_two_samples_on_and_a_gap_clears_the_samples():
    tb = np.arange(0.0, 10.0, 0.1)
    tg = np.arange(0.05, 10.0, 0.2)
    step = np.where(tb >= 4.95, 5.0, 0.0)
    out = {round(t, 2): b for t, b, _ in _feed(list(zip(tb, step)), [(t, 0.0) for t in tg])}
    assert out[4.85] == 0.0 and out[5.05] == 0.0 and out[5.25] == 5.0
    level = BaroLevel(1.0, 10.0, 1.5)
    level.push_gnss(0, 0.0)
    level.push_baro(100_000, 7.0)
    assert level.end_m(100_000) == pytest.approx(7.0)
    assert level.centred_m(0) == pytest.approx(7.0) and level.centred_m(50_000) is None  # no GNSS sample there
    level.push_baro(2_000_000, 1.0)  # 2 s after the last Doppler: no reference to carry it
    assert not level.r and level.end_m(2_000_000) is None
    level.push_gnss(2_100_000, math.nan)
    assert level.t_gnss_us is None


def _dkla_series():
    cfg = config_from_dict({})
    baro, gnss = [], []
    for s in open_log(str(DKLA), cfg.ingest):
        if s.__class__ is BaroHeight and s.boot == 0:
            baro.append((s.t_us * 1e-6, s.height_ref_m))
        elif s.__class__ is GnssHeight and s.boot == 0 and s.vel_up_mps is not None:
            gnss.append((s.t_us * 1e-6, s.vel_up_mps))
    return np.asarray(baro), gnss


@pytest.mark.realdata
@pytest.mark.skipif(not DKLA.exists(), reason="no shared flight logs")
def test_on_a_real_flight_spikes_in_the_baro_stay_out_of_the_reading_and_a_ramp_does_not():
    """dkla_log171 with a 3 m spike in one baro sample every 5 s: read from the
    median levels the baro/Doppler reading hardly moves; read from the latest
    sample its 99.9th percentile grows by metres. A 0.5 m/s baro ramp
    injected into the same flight reads 4 m above the unfaulted reading as
    soon either way, to a baro interval."""
    baro, gnss = _dkla_series()
    assert len(baro) > 2000 and len(gnss) > 1000

    def p999(series, span_s):
        e = [x for _, _, x in _feed(series, gnss, span_s=span_s) if x is not None]
        return float(np.percentile(np.abs(e), 99.9))

    spiked = baro.copy()
    spiked[::55, 1] += 3.0  # one sample in 55 at 11 Hz
    clean_median, spiked_median = p999(baro, 1.0), p999(spiked, 1.0)
    clean_latest, spiked_latest = p999(baro, None), p999(spiked, None)
    assert spiked_median < clean_median + 0.3
    assert spiked_latest > clean_latest + 1.5
    assert clean_median <= clean_latest  # its white noise averaged too

    onset = 150.0
    ramped = baro.copy()
    ramped[:, 1] += np.where(ramped[:, 0] >= onset, 0.5 * (ramped[:, 0] - onset), 0.0)
    first = {}
    for span_s in (1.0, None):
        base = {round(t, 2): x for t, _, x in _feed(baro, gnss, span_s=span_s)}
        crossed = [t for t, _, x in _feed(ramped, gnss, span_s=span_s)
                   if t > onset and x is not None and base.get(round(t, 2)) is not None
                   and x - base[round(t, 2)] > 4.0]
        assert crossed, span_s
        first[span_s] = crossed[0]
    assert first[1.0] - first[None] <= 0.21  # the median of three: at most one reading (5 Hz) later
