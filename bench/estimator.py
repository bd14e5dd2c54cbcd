"""Cost of one three-channel step: mavnav's bank against a straightforward
filterpy KalmanFilter implementation of the same model, same epochs, same run.

The filterpy baseline is the textbook form of the model (MODEL.md section 4,
last paragraph): the baro Gauss-Markov noise augmented into the state (5
states), one KalmanFilter per channel, F/Q/B rebuilt for each step's T,
predict(u = f_up - g) then update with the rows present.

Also: the end-to-end estimator cost (epoch builder + bank) for an hour of
200 Hz IMU with 50 Hz baro, 10 Hz GNSS, 20 Hz rangefinder, extrapolated from
a simulated stretch.

    .venv/bin/python bench/estimator.py [--seconds 120]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from filterpy.kalman import KalmanFilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: tests.support

from mavnav.bank import ChannelBank  # noqa: E402
from mavnav.channel import CHANNELS, Model, process_noise, transition  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.epochs import EpochBuilder, EpochStart  # noqa: E402
from tests.support.synthetic import Schedule, TrueSensors, paper_flight  # noqa: E402

SENSORS = TrueSensors(sigma_a_mps2=0.2, alpha_a_per_s=1.0, sigma_bb_m=1.0, gamma_bb_per_s=2.0, sigma_z_m=1.5)
CFG = config_from_dict({
    "sensors": {"ins": {"sigma_a_mps2": 0.2}, "baro": {"gamma_bb_per_s": 2.0},
                "gnss": {"sigma_z_m": 1.5, "use_v_acc": False}},
})


def make_epochs(seconds: float):
    sched = Schedule(duration_s=seconds, imu_dt_s=0.005, baro_every=4, gnss_every=20, rng_every=10)
    flight = paper_flight(seed=1, sensors=SENSORS, schedule=sched)
    b = EpochBuilder(CFG)
    eps = []
    for s in flight.samples:
        eps.extend(b.push(s))
    return flight, eps


def run_bank(eps, model):
    bank = ChannelBank(model)
    t0 = time.perf_counter()
    for ep in eps:
        if isinstance(ep, EpochStart):
            bank.start(ep.t_us, ep.baro_m)
        else:
            bank.step(ep)
    return time.perf_counter() - t0, bank


def run_filterpy(eps, model):

    kfs = []
    t0 = time.perf_counter()
    for ep in eps:
        if isinstance(ep, EpochStart):
            kfs = []
            for _ in CHANNELS:
                kf = KalmanFilter(dim_x=5, dim_z=2, dim_u=1)
                kf.x = np.zeros(5)
                kf.P = np.diag(list(model.p0_diag) + [model.sigma_bb_m**2])
                kf.update(np.array([ep.baro_m]), R=np.array([[0.0]]), H=np.array([[1.0, 0, 1, 0, 1]]))
                kfs.append(kf)
            continue
        T = ep.dt_s
        phi = math.exp(-model.gamma_bb_per_s * T)
        F = np.eye(5)
        F[:4, :4] = transition(T)
        F[4, 4] = phi
        Q = np.zeros((5, 5))
        Q[:4, :4] = process_noise(T, model)
        Q[4, 4] = model.sigma_bb_m**2 * (1 - phi * phi)
        B = np.array([[0.5 * T * T], [T], [0.0], [0.0], [0.0]])
        u = np.array([ep.dv_mps / T])  # mean f_up - g over the step
        for kind, kf in zip(CHANNELS, kfs):
            kf.F, kf.Q, kf.B = F, Q, B
            kf.predict(u=u)
            Hs, zs, Rs = [], [], []
            if ep.baro_m is not None:
                Hs.append([1.0, 0, 1, 0, 1]); zs.append(ep.baro_m); Rs.append(0.0)
            aux = ep.gnss if kind == "gnss" else ep.rng if kind == "rangefinder" else None
            if aux is not None:
                Hs.append([1.0, -aux.age_s, 0, 0, 0]); zs.append(aux.height_m); Rs.append(aux.sigma_m**2)
            if zs:
                kf.update(np.array(zs), R=np.diag(Rs), H=np.array(Hs))
    return time.perf_counter() - t0, kfs


def run_end_to_end(flight, model):
    bank = ChannelBank(model)
    b = EpochBuilder(CFG)
    t0 = time.perf_counter()
    for s in flight.samples:
        for ep in b.push(s):
            if isinstance(ep, EpochStart):
                bank.start(ep.t_us, ep.baro_m)
            else:
                bank.step(ep)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=120.0, help="simulated flight length")
    args = ap.parse_args()
    model = Model.from_config(CFG)
    flight, eps = make_epochs(args.seconds)
    n_steps = sum(not isinstance(e, EpochStart) for e in eps)
    run_bank(eps[:50], model)  # JIT warm-up (compiled once, cached on disk)
    t_bank = min(run_bank(eps, model)[0] for _ in range(3))
    t_fp = min(run_filterpy(eps, model)[0] for _ in range(2))
    us_bank = t_bank / n_steps * 1e6
    us_fp = t_fp / n_steps * 1e6
    print(f"epochs: {n_steps} (50 Hz baro, 200 Hz IMU, {args.seconds:g} s)")
    print(f"three-channel step, mavnav bank     : {us_bank:8.2f} us")
    print(f"three-channel step, filterpy (5-st.): {us_fp:8.2f} us")
    print(f"ratio filterpy / mavnav             : {us_fp / us_bank:8.1f}x")
    t_e2e = min(run_end_to_end(flight, model) for _ in range(2))
    n_imu = len(flight.t_us)
    hour = t_e2e / n_imu * 200 * 3600
    print(f"end to end (epoch builder + bank)   : {t_e2e / n_imu * 1e6:8.2f} us per IMU sample; "
          f"an hour of 200 Hz IMU: {hour:.1f} s")
    print(f"filterpy steps for the same hour     : {us_fp * 50 * 3600 / 1e6:.1f} s")


if __name__ == "__main__":
    main()
