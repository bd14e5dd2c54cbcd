"""The epoch builder: INS pre-integration, aux alignment, gaps."""

from __future__ import annotations

import math

import pytest

from mavnav.config import load_config
from mavnav.epochs import EpochBuilder, EpochStart
from mavnav.samples import BaroHeight, GnssHeight, RangeHeight, Reboot, SpecificForceUp

G = 9.80665


def imu(t_s, f=G):
    return SpecificForceUp(int(round(t_s * 1e6)), 0.0, 0, f, "test")


def baro(t_s, h=0.0, p_pa=None):
    # a distinct pressure per sample unless given: exact repeats are a resent measurement
    return BaroHeight(int(round(t_s * 1e6)), 0.0, 0, h, 1e5 - 12.0 * h - t_s if p_pa is None else p_pa, 1)


def rng(t_s, h=1.0):
    return RangeHeight(int(round(t_s * 1e6)), 0.0, 0, h, h, "test")


def gnss(t_s, h=1.0):
    return GnssHeight(int(round(t_s * 1e6)), 0.0, 0, h, h, None, 3, 10)


def feed(b, items):
    out = []
    for s in items:
        out += b.push(s)
    return out


def test_zero_order_hold_integration_is_exact_for_piecewise_constant_acceleration():
    b = EpochBuilder(load_config(None))
    # 1 m/s^2 up from 0.0 to 0.05 s, then 3 m/s^2 from 0.05 to 0.1 s; epoch at 0.1 s
    eps = feed(b, [imu(0.0, G + 1.0), baro(0.0), imu(0.05, G + 3.0), imu(0.1, G), baro(0.1)])
    assert isinstance(eps[0], EpochStart)
    ep = eps[1]
    assert ep.dt_s == pytest.approx(0.1)
    assert ep.dv_mps == pytest.approx(1.0 * 0.05 + 3.0 * 0.05)
    # p = 0.5*1*0.05^2 + (0.05*0.05 + 0.5*3*0.05^2)
    assert ep.dp_m == pytest.approx(0.5 * 0.0025 + 0.05 * 0.05 + 0.5 * 3 * 0.0025)


def test_aux_stream_leading_the_baro_clock_at_the_same_rate_is_not_lost():
    """Rangefinder 30 ms ahead of the baro, both at 10 Hz: every sample must be
    used at the next epoch (keeping only the newest lost them all)."""
    b = EpochBuilder(load_config(None))
    items = [imu(0.0), baro(0.0)]
    for k in range(1, 50):
        t = 0.1 * k
        items += [rng(t - 0.07), imu(t), baro(t)]
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    used = [e for e in eps if e.rng is not None]
    assert len(used) == len(eps) and all(abs(e.rng.age_s - 0.07) < 1e-9 for e in used)
    assert b.counters["rng_superseded"] == 0


def test_every_pending_aux_sample_is_used_averaged_and_future_ones_wait():
    b = EpochBuilder(load_config(None))
    eps = feed(b, [imu(0.0), baro(0.0), gnss(0.02, 1.0), gnss(0.05, 2.0), gnss(0.15, 3.0), imu(0.1), baro(0.1),
                   imu(0.2), baro(0.2)])
    e1, e2 = [e for e in eps if not isinstance(e, EpochStart)]
    sigma = load_config(None).sensors.gnss.sigma_z_m
    assert e1.gnss.height_m == pytest.approx(1.5) and e1.gnss.age_s == pytest.approx(0.065)
    assert e1.gnss.sigma_m == pytest.approx(sigma / math.sqrt(2))
    assert e2.gnss.height_m == 3.0 and e2.gnss.age_s == pytest.approx(0.05)
    assert b.counters["gnss_used"] == 3 and b.counters["gnss_superseded"] == 0


def test_baro_gap_forces_epochs_and_restarts_the_differencing():
    cfg = load_config(None)
    b = EpochBuilder(cfg)
    items = [imu(0.0), baro(0.0)]
    for k in range(1, 5):  # the baro shows its 25 Hz cadence
        items += [imu(0.01 * k)] + ([baro(0.01 * k)] if k % 4 == 0 else [])
    items += [imu(0.04 + 0.01 * k) for k in range(1, 101)]  # 1 s of IMU, no baro
    items += [baro(1.04)] + [imu(1.04 + 0.01 * k) for k in range(1, 5)] + [baro(1.08)]
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    forced = [e for e in eps if e.baro_m is None]
    assert len(forced) >= int(0.9 / cfg.filter.max_epoch_gap_s)
    assert all(e.dt_s <= cfg.filter.max_epoch_gap_s + 0.011 for e in forced)
    after = [e for e in eps if e.baro_m is not None and e.t_us > 1_000_000]
    assert after[0].baro_restart and not after[-1].baro_restart


def test_late_aux_is_dropped_and_counted_and_a_reboot_resets():
    b = EpochBuilder(load_config(None))
    feed(b, [imu(1.0), baro(1.0), imu(1.1), baro(1.1)])
    feed(b, [gnss(0.5)])  # 0.6 s older than the last epoch
    assert b.counters["gnss_late"] == 1
    b.push(Reboot(t_us=10_000, recv_s=0.0, boot=1, last_t_us=1_100_000))
    assert not b.started
    eps = feed(b, [imu(0.01), baro(0.02)])
    assert isinstance(eps[0], EpochStart) and eps[0].t_us == 20_000
    assert math.isfinite(eps[0].baro_m)


# ---------------------------------------------------------------- real-input timing (issue 12)


def test_a_lagging_imu_never_integrates_backwards():
    """Baro processed ahead of a quiet IMU, then the IMU catches up with
    samples older than that epoch: every epoch integrates exactly dt of the
    constant acceleration, never a negative segment or an over-weighted one."""
    b = EpochBuilder(load_config(None))
    items = [imu(0.0, G + 1.0), baro(0.0)]
    for k in range(1, 40):
        t = 0.1 * k
        items += [baro(t), imu(t - 0.3, G + 1.0)]  # the IMU lags the baro by 0.3 s
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    assert len(eps) > 30
    for e in eps:
        assert e.dv_mps == pytest.approx(1.0 * e.dt_s, abs=1e-9)


def _quiet_ins_config(sigma_a_mps2=1e-4):
    """Defaults with an INS model whose own white noise is negligible, so the
    measured scatter is all beyond the model."""
    cfg = load_config(None)
    ins = cfg.sensors.ins.model_copy(update={"sigma_a_mps2": sigma_a_mps2})
    return cfg.model_copy(update={"sensors": cfg.sensors.model_copy(update={"ins": ins})})


def _epochs_with_imu(rate_hz, seed, duration_s=20.0, sigma=1.0, cfg=None):
    import numpy as np

    rng_ = np.random.default_rng(seed)
    b = EpochBuilder(_quiet_ins_config() if cfg is None else cfg)
    items = []
    n_imu = int(duration_s * rate_hz)
    for k in range(n_imu):
        items.append(imu(k / rate_hz, G + sigma * rng_.standard_normal()))
    items += [baro(0.1 * k) for k in range(int(duration_s * 10))]
    items.sort(key=lambda s: s.t_us)
    out = []
    for s in items:
        for e in b.push(s):
            if not isinstance(e, EpochStart):
                out.append((e, b.last_dv_var_m2ps2))
    return b, out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_imu_scatter_variance_is_small_at_high_rates_and_dominates_at_telemetry_rates(seed):
    """What a held snapshot misses is sigma^2 * tau * T per epoch: with 1 m/s^2
    of sample scatter, 200 Hz gives 5e-4 (m/s)^2 per 0.1 s epoch, 4 Hz about
    0.025; and the dv error it stands for is really that large."""
    import numpy as np

    _, fast = _epochs_with_imu(200.0, seed)
    _, slow = _epochs_with_imu(4.0, seed)
    v_fast = np.median([v for _, v in fast[50:]])
    v_slow = np.median([v for _, v in slow[50:]])
    assert v_fast == pytest.approx(1.0 * 0.005 * 0.1, rel=0.3)
    assert 0.01 < v_slow < 0.05
    # calibration: the true dv (zero, the mean force is g) against the held-sample dv
    dv_slow = np.array([e.dv_mps for e, _ in slow[50:]])
    var_pred = np.array([v for _, v in slow[50:]])
    # epochs inside one held sample share its error: compare summed over 1 s blocks
    blocks = len(dv_slow) // 10
    err = dv_slow[: blocks * 10].reshape(blocks, 10).sum(axis=1)
    pred = var_pred[: blocks * 10].reshape(blocks, 10).sum(axis=1)
    ratio = float(np.mean(err ** 2) / np.mean(pred))
    assert 0.5 < ratio < 2.0


@pytest.mark.parametrize("seed", [1, 2])
def test_imu_scatter_within_the_modelled_ins_noise_adds_nothing(seed):
    """The filters' process noise already carries the INS model's white noise
    (per sample q_a(T)^2 = 2 sigma_a^2 / (alpha_a T)): samples scattered by
    exactly that add (almost) nothing, samples scattered by twice its RMS add
    the 3 q_a^2 beyond it."""
    import numpy as np

    from mavnav.channel import Model, accel_noise_q

    cfg = load_config(None)
    q = accel_noise_q(1.0 / 200.0, Model.from_config(cfg))  # 2 m/s^2 at 200 Hz
    _, same = _epochs_with_imu(200.0, seed, sigma=q, cfg=cfg)
    _, twice = _epochs_with_imu(200.0, seed, sigma=2.0 * q, cfg=cfg)
    model_dv_var = q * q * 0.005 * 0.1  # the model's own, per 0.1 s epoch
    assert np.median([v for _, v in same[50:]]) < 0.1 * model_dv_var
    assert np.median([v for _, v in twice[50:]]) == pytest.approx(3.0 * model_dv_var, rel=0.3)


def test_imu_silence_beyond_the_hold_limit_is_unknown_acceleration_not_a_replayed_sample():
    cfg = load_config(None)
    b = EpochBuilder(cfg)
    items = [imu(0.0, G + 5.0), baro(0.0)] + [imu(0.01 * k, G + 5.0) for k in range(1, 11)]
    items += [baro(0.1 * k) for k in range(1, 31)]  # 3 s of baro, the IMU silent after 0.1 s
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    dv = sum(e.dv_mps for e in eps)
    hold = max(cfg.filter.imu_hold_max_s, cfg.filter.imu_hold_intervals * 0.01)
    assert dv == pytest.approx(5.0 * (0.1 + hold), abs=0.06)  # not 5 m/s^2 for 3 s
    assert b.counters["imu_unknown_us"] > 2_000_000
    assert b.last_dv_var_m2ps2 >= cfg.filter.kinematic_accel_sigma_mps2 ** 2 * 0.1 * 0.99


def test_a_2hz_telemetry_baro_is_slow_not_a_gap_and_late_gnss_is_used():
    """Telemetry: baro and GNSS at 2 Hz, IMU at 4 Hz, GNSS stamped 0.3 s
    before it arrives (after the epoch it belongs to): no forced epoch, no
    differencing restart, every GNSS sample used."""
    b = EpochBuilder(load_config(None))
    items = []
    for k in range(0, 120):
        items.append(imu(0.25 * k))
    for k in range(0, 60):
        items.append(baro(0.5 * k + 0.01))
    items.sort(key=lambda s: s.t_us)
    out = []
    n_gnss = 0
    for s in items:
        out += b.push(s)
        if isinstance(s, BaroHeight) and s.t_us > 1_000_000:
            out += b.push(gnss(s.t_us * 1e-6 - 0.3))
            n_gnss += 1
    eps = [e for e in out if not isinstance(e, EpochStart)]
    assert b.counters["forced_epochs"] == 0 and b.counters["baro_restarts"] == 0
    assert b.counters["gnss_used"] >= n_gnss - 1 and b.counters["gnss_late"] == 0
    assert sum(e.gnss is not None for e in eps) >= n_gnss - 2


def test_a_resent_baro_value_makes_no_epoch():
    """Telemetry at 10 Hz from a 5 Hz sensor: every other message repeats
    the previous pressure exactly. Those are not new measurements (when the
    rule is on: it is off by default, see FilterConfig.baro_repeat_max_s)."""
    cfg = load_config(None)
    b = EpochBuilder(cfg.model_copy(update={"filter": cfg.filter.model_copy(update={"baro_repeat_max_s": 1.0})}))
    items = []
    for k in range(100):
        t = 0.1 * k
        items.append(imu(t))
        p = 1e5 - (k // 2) * 0.7  # changes every second message
        items.append(baro(t, h=(k // 2) * 0.06, p_pa=p))
    eps = [e for e in feed(b, items) if not isinstance(e, EpochStart)]
    assert b.counters["baro_repeated"] == 50
    assert len(eps) == 49 and all(e.dt_s == pytest.approx(0.2) for e in eps)


def _baro_with_gauss_markov(seed, white_m, cfg, dt_s=0.2, n=200, spike_at=None):
    """A climbing vehicle whose baro carries the model's own Gauss-Markov noise
    u (sigma_bb, gamma_bb of ``cfg``) plus white noise ``white_m``."""
    import numpy as np

    r = np.random.default_rng(seed)
    c = cfg.sensors.baro
    phi = math.exp(-c.gamma_bb_per_s * dt_s)
    u = c.sigma_bb_m * r.standard_normal()
    items = []
    for k in range(n):
        t = dt_s * k
        u = phi * u + c.sigma_bb_m * math.sqrt(1.0 - phi * phi) * r.standard_normal()
        h = 2.0 * t + u + white_m * r.standard_normal() + (8.0 if k == spike_at else 0.0)
        items += [imu(t), baro(t, h=h)]
    return items


@pytest.mark.parametrize("seed,sigma", [(1, 0.1), (2, 0.3), (3, 0.45)])
def test_baro_white_noise_is_measured_from_the_samples(seed, sigma):
    """A climbing vehicle, the modelled Gauss-Markov u and white noise sigma
    on the baro: the white estimate is within 20 % (a median of second
    differences less u's share: the climb and one spike do not move it)."""
    import numpy as np

    cfg = load_config(None)
    b = EpochBuilder(cfg)
    eps = [e for e in feed(b, _baro_with_gauss_markov(seed, sigma, cfg, n=300, spike_at=150))
           if not isinstance(e, EpochStart)]
    # the window holds 61 samples: the median over the last 240 epochs
    # spans about four windows
    white = np.array([e.baro_white_var_m2 for e in eps[-240:]])
    assert math.sqrt(float(np.median(white))) == pytest.approx(sigma, rel=0.2)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_modelled_gauss_markov_baro_noise_is_not_counted_again_as_white(seed):
    """A baro with only the model's u (here sigma_bb 1 m, gamma_bb 2 /s at
    50 Hz, whose second differences look like 0.16 m of white noise): the
    filters already model it, so once the window is full (the significance
    test decides then; before, the prior and the filling window's estimate
    stand, tests/test_baro_white_prior.py) no white noise is passed on."""
    cfg = load_config(None)
    baro_cfg = cfg.sensors.baro.model_copy(update={"sigma_bb_m": 1.0, "gamma_bb_per_s": 2.0})
    cfg = cfg.model_copy(update={"sensors": cfg.sensors.model_copy(update={"baro": baro_cfg})})
    b = EpochBuilder(cfg)
    eps = [e for e in feed(b, _baro_with_gauss_markov(seed, 0.0, cfg, dt_s=0.02, n=1000))
           if not isinstance(e, EpochStart)]
    white = [e.baro_white_var_m2 for e in eps][cfg.sensors.baro.white_window:]
    assert len(white) > 900
    assert sum(v > 0.0 for v in white) < 0.02 * len(white)
    assert max(white) < 0.1 ** 2


# ---------------------------------------------------------------------- the compiled IMU pass


def _rough_stream(seed):
    """IMU at a jittery 50-400 Hz with silences beyond the hold, samples not
    increasing, IMU before the first baro (more than a batch), a baro that
    goes quiet (forced epochs), GNSS and rangefinder, and a reboot."""
    import numpy as np

    r = np.random.default_rng(seed)
    items = []
    for boot in (0, 1):
        t = 0.0
        items_boot = []
        rate = float(r.choice([50.0, 200.0, 400.0]))
        while t < 30.0:
            t += float(r.exponential(1.0 / rate)) if r.random() < 0.3 else 1.0 / rate
            if r.random() < 0.002:
                t += float(r.uniform(0.05, 1.5))  # silent beyond the hold
            items_boot.append(imu(t, G + float(r.standard_normal() * r.choice([0.1, 3.0]))))
            if r.random() < 0.01:
                items_boot.append(imu(t - float(r.uniform(0.0, 0.02))))  # behind the latest
        for k in range(int(2.0 / 0.04), int(30.0 / 0.04)):
            if 12.0 < k * 0.04 < 14.0:
                continue  # the baro goes quiet: forced epochs
            items_boot.append(baro(k * 0.04 + r.uniform(0.0, 0.004), h=float(r.standard_normal())))
        items_boot += [gnss(0.2 * k + 0.05) for k in range(150)]
        items_boot += [rng(0.05 * k + 0.01) for k in range(600)]
        items_boot.sort(key=lambda s: s.t_us)
        if boot:
            items.append(Reboot(t_us=0, recv_s=0.0, boot=1, last_t_us=items[-1].t_us))
        items += items_boot
    return items


def _run_both(items, cfg):
    out = []
    for compiled in (False, True):
        b = EpochBuilder(cfg, compiled=compiled)
        eps = [repr(e) for s in items for e in b.push(s)]
        out.append((eps, sorted(b.counters.items())))
    return out


@pytest.mark.parametrize("seed", [1] + [pytest.param(s, marks=pytest.mark.slow) for s in (2, 3, 4)])
def test_compiled_imu_pass_gives_the_reference_floats(seed):
    """imu_kernel against _take_imu_reference/_integrate_reference: the same
    epochs (every float, by repr) and the same counters."""
    cfg = load_config(None)
    ref, comp = _run_both(_rough_stream(seed), cfg)
    assert len(ref[0]) > 1000
    assert any(k == "imu_unknown_us" for k, _ in ref[1]) and any(k == "forced_epochs" for k, _ in ref[1])
    assert comp == ref


def test_compiled_imu_pass_gives_the_reference_floats_on_a_recorded_flight():
    from mavnav.ingest import TlogSource

    from tests.support.paths import SITL_LOGS

    cfg = load_config(None)
    items = list(TlogSource(SITL_LOGS / "px4_hover_gnss_step.tlog", cfg.ingest))
    ref, comp = _run_both(items, cfg)
    assert len(ref[0]) > 1000
    assert comp == ref


def test_baro_white_noise_median_window_kept_in_order_is_the_sorted_window():
    """The ordered window _baro_noise keeps gives the median sorted() of the
    window gives, sample by sample (ties and repeats included), and a NaN
    difference falls back to sorting."""
    import numpy as np

    r = np.random.default_rng(5)
    b = EpochBuilder(load_config(None))
    b.push(imu(0.0))
    b.push(baro(0.0))
    hs = np.round(r.standard_normal(400) * 0.3, 2)  # rounded: many equal differences
    for k, h in enumerate(hs, 1):
        b.push(baro(0.05 * k, h=float(h)))
        assert b._baro_d2_sorted == sorted(b._baro_d2)
    b._baro_noise(math.nan, 10 ** 9)
    assert b._baro_d2_sorted is None
