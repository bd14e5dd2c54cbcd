"""The differencing filter against an independent reference: the textbook
state-augmented 5-state Kalman filter (baro noise u in the state), built with
filterpy's KalmanFilter, on the same simulated data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from mavnav.channel import GB, N_PAPER, Model, process_noise, transition
from mavnav.epochs import EpochBuilder, EpochStart
from tests.support.synthetic import Schedule, TrueSensors, paper_flight

from tests.support.estimator import config_for, run_channels

SENSORS = TrueSensors(sigma_a_mps2=0.2, alpha_a_per_s=1.0, sigma_bb_m=1.0, gamma_bb_per_s=2.0, sigma_z_m=1.5)


def measured_noise(flight, cfg):
    """``{t_us: (dv_var_m2ps2, baro_white_var_m2)}`` of the epochs the epoch
    builder makes of ``flight``: the input noise it measures beyond the model."""
    builder = EpochBuilder(cfg)
    out = {}
    for s in flight.samples:
        for ep in builder.push(s):
            if not isinstance(ep, EpochStart):
                out[ep.t_us] = (ep.dv_var_m2ps2, ep.baro_white_var_m2)
    return out


def augmented_reference(flight, model: Model, use_gnss: bool, sigma_z_m: float, dv_var_at=None):
    """5-state augmented filter fed the raw samples directly (no EpochBuilder):
    state [H, Vz, dH, da, u], baro z = H + dH + u with no white noise. The
    process noise adds ``dv_var_at[t_us]`` (the IMU scatter beyond the model
    that the epoch builder measured for the step ending at ``t_us``) in the
    same shape as the channel filter."""
    dv_var_at = dv_var_at or {}
    g = model.gravity_mps2
    kf = None
    t_prev = None
    f_latest = None  # newest IMU sample: it holds over the coming interval
    f_hold = None
    gnss = None
    out = []
    for s in flight.samples:
        name = type(s).__name__
        if name == "SpecificForceUp":
            f_latest = s.f_up_mps2
            continue
        if name == "GnssHeight":
            gnss = s if kf is not None else None
            continue
        if name != "BaroHeight":
            continue
        if kf is None:
            kf = KalmanFilter(dim_x=5, dim_z=1, dim_u=1)
            kf.x = np.zeros(5)
            kf.P = np.diag(list(model.p0_diag) + [model.sigma_bb_m**2])
            kf.update(np.array([s.height_ref_m]), R=np.array([[0.0]]), H=np.array([[1.0, 0, 1, 0, 1]]))
            t_prev, f_hold = s.t_us, f_latest
            continue
        T = (s.t_us - t_prev) * 1e-6
        phi = math.exp(-model.gamma_bb_per_s * T)
        F = np.eye(5)
        F[:4, :4] = transition(T)
        F[4, 4] = phi
        Q = np.zeros((5, 5))
        Q[:4, :4] = process_noise(T, model, dv_var_at.get(s.t_us, 0.0))
        Q[4, 4] = model.sigma_bb_m**2 * (1 - phi * phi)
        kf.F, kf.Q = F, Q
        kf.B = np.array([[0.5 * T * T], [T], [0.0], [0.0], [0.0]])
        kf.predict(u=np.array([f_hold - g]))
        Hs, zs, Rs = [[1.0, 0, 1, 0, 1]], [s.height_ref_m], [0.0]
        used_gnss = use_gnss and gnss is not None and gnss.t_us == s.t_us
        if used_gnss:
            Hs.append([1.0, 0, 0, 0, 0])
            zs.append(gnss.height_ref_m)
            Rs.append(sigma_z_m**2)
        gnss = None
        kf.update(np.array(zs), R=np.diag(Rs), H=np.array(Hs))
        out.append((s.t_us, kf.x[:4].copy(), kf.P[:4, :4].copy(), used_gnss))
        t_prev, f_hold = s.t_us, f_latest
    return out


@pytest.mark.parametrize("kind", ["baro", "gnss"])
@pytest.mark.parametrize("irregular", [pytest.param(0.0, marks=pytest.mark.slow), 0.4])
def test_differencing_equals_augmented_filter(kind, irregular):
    sched = Schedule(duration_s=20.0, imu_dt_s=0.02, irregular=irregular, baro_every=1, gnss_every=5)
    flight = paper_flight(seed=11, sensors=SENSORS, schedule=sched)
    cfg = config_for(SENSORS, height_prior="p0")
    # the simulated baro noise is the modelled u alone, and the augmented form
    # has no white noise: the builder's white-noise meter is off here (it
    # passes its prior and the filling window's estimate over the first
    # samples; that it passes none on u alone once the window is full is
    # tests/test_epochs.py's)
    baro = cfg.sensors.baro.model_copy(update={"white_max_m": 0.0})
    cfg = cfg.model_copy(update={"sensors": cfg.sensors.model_copy(update={"baro": baro})})
    model = Model.from_config(cfg)
    hist, _ = run_channels(flight, cfg, kinds=(kind,))
    mine = [(t, x, P) for t, x, P, out in hist[kind] if out is not None]
    noise = measured_noise(flight, cfg)
    assert not any(white for _, white in noise.values())
    # the simulated IMU noise is the modelled one: what the builder measures
    # beyond it is small but not nothing, and enters both filters alike
    assert sum(dv > 0.0 for dv, _ in noise.values()) > 100
    dv_var_at = {t: dv for t, (dv, _) in noise.items()}
    ref = augmented_reference(flight, model, use_gnss=(kind == "gnss"), sigma_z_m=SENSORS.sigma_z_m,
                              dv_var_at=dv_var_at)
    assert len(mine) == len(ref) > 900
    if kind == "gnss":
        assert sum(r[3] for r in ref) > 150  # GNSS rows really exercised
        assert sum(out.rows == ("baro", "gnss") for *_, out in hist[kind][1:]) > 150
    for (t1, x1, P1), (t2, x2, P2, _) in zip(mine, ref):
        assert t1 == t2
        # the GNSS error state is off (white GNSS noise): exactly 0, no variance
        assert x1[GB] == 0.0 and not P1[GB].any()
        np.testing.assert_allclose(x1[:N_PAPER], x2, rtol=1e-7, atol=1e-8)
        np.testing.assert_allclose(P1[:N_PAPER, :N_PAPER], P2, rtol=1e-6, atol=1e-10)


def test_reference_catches_a_wrong_baro_noise():
    """The comparison is sharp: a 5 % error in gamma_bb is visible."""
    sched = Schedule(duration_s=10.0, imu_dt_s=0.02, baro_every=1, gnss_every=5)
    flight = paper_flight(seed=3, sensors=SENSORS, schedule=sched)
    cfg = config_for(SENSORS, height_prior="p0")
    wrong = config_for(TrueSensors(**{**SENSORS.__dict__, "gamma_bb_per_s": SENSORS.gamma_bb_per_s * 1.05}),
                       height_prior="p0")
    hist, _ = run_channels(flight, wrong, kinds=("gnss",))
    dv_var_at = {t: dv for t, (dv, _) in measured_noise(flight, cfg).items()}
    ref = augmented_reference(flight, Model.from_config(cfg), use_gnss=True, sigma_z_m=SENSORS.sigma_z_m,
                              dv_var_at=dv_var_at)
    P_mine = hist["gnss"][-1][2][:N_PAPER, :N_PAPER]
    assert not np.allclose(P_mine, ref[-1][2], rtol=1e-6, atol=1e-10)
