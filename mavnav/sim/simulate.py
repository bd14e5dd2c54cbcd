"""The simulator: scenario + seed -> MAVLink telemetry (tlog bytes) with known truth.

Pipeline (all vectorised except the Gauss-Markov recursions and the encoder):

1. sample times per message type from the scenario's rates (random phase,
   small jitter), in *simulation time* (seconds from the start);
2. truth kinematics at those times (:mod:`mavnav.sim.trajectory`);
3. sensor models (:mod:`mavnav.sim.sensors`) with the true biases and noise;
4. faults on the sensor values, then which messages are sent (reboots,
   rate drops, silent dropouts) and received (link losses);
5. vehicle clock per message (restarts at a reboot), sequence numbers per
   boot, receive time = start + simulation time + latency (FIFO link);
6. pymavlink encoding (:mod:`mavnav.sim.encode`).

Scenario time (fault onsets) = simulation time + ``boot_time_at_start_s``.
Deterministic for a given scenario and seed: every random draw comes from a
stream keyed by ``(seed, stream id)``, so enabling one message type does not
change another's noise.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import frames
from .encode import encode_tlog
from .effects import height_error_m, keeps, out_of_range_reading_m, spikes
from .faults import active_labels, additive_offset, describe_fault, sidecar_path, window_mask, write_sidecar
from .scenario import MESSAGE_TYPES, Fault, Scenario
from .sensors import (
    accel_noise_std,
    body_rates,
    gauss_markov,
    hold_latest,
    isa_altitude_m,
    mat_nb,
    pressure_from_height,
    specific_force_body,
)
from .trajectory import Kinematics, TruthTrajectory, ground_height_m

IMU_TYPES = ("HIGHRES_IMU", "RAW_IMU", "SCALED_IMU", "SCALED_IMU2")
MAG_NED_GAUSS = np.array([0.21, 0.01, 0.43])
IMU_TEMPERATURE_C = 45.0

# random stream ids (never reuse one for another purpose)
_S_TIMES, _S_LINK, _S_BARO, _S_GNSS_WHITE, _S_GNSS_GM, _S_RNG, _S_ATT, _S_EST = 1, 2, 20, 21, 22, 23, 24, 25
_S_IMU = {name: 10 + k for k, name in enumerate(IMU_TYPES)}
_S_FAULT = 100


def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([seed, stream])


@dataclass(frozen=True)
class Clock:
    """Vehicle clock: boot 0 from ``boot_time_at_start_s``; each reboot restarts at 0."""

    boot_offset_s: float
    reboot_onsets_sim_s: Tuple[float, ...]

    def boot(self, t_sim: np.ndarray) -> np.ndarray:
        return np.searchsorted(np.asarray(self.reboot_onsets_sim_s, dtype=float), t_sim, side="right")

    def vehicle_time(self, t_sim: np.ndarray) -> np.ndarray:
        b = self.boot(t_sim)
        base = np.concatenate([[-self.boot_offset_s], np.asarray(self.reboot_onsets_sim_s, dtype=float)])
        return np.asarray(t_sim, dtype=float) - base[b]


@dataclass(frozen=True)
class Truth:
    """Truth at a fixed rate (``scenario.truth_rate_hz``); column names as in the CSV."""

    columns: Dict[str, np.ndarray]

    def __getitem__(self, key: str) -> np.ndarray:
        return self.columns[key]

    def to_csv(self, path: Union[str, Path]) -> None:
        write_truth_csv(path, self.columns)


@dataclass
class SimResult:
    """Everything a caller needs: the tlog bytes, truth, fault windows and raw streams.

    ``streams[msg]`` holds the sensor values per message type in SI units
    (``t_sim`` simulation time, ``sent``/``received`` masks, faulted values);
    ``trajectory.sample(t_sim)`` gives the truth at any simulation time.
    """

    scenario: Scenario
    seed: int
    tlog: bytes
    truth: Truth
    faults: Tuple[dict, ...]
    streams: Dict[str, dict]
    trajectory: TruthTrajectory
    clock: Clock
    timings_s: Dict[str, float] = field(default_factory=dict)
    # sensor series before message selection: "baro" (t_sim, height_m, noise_m, pressure_pa),
    # "rangefinder" (t_sim, range_m, quality, slant_true_m)
    series: Dict[str, dict] = field(default_factory=dict)

    def sidecar(self) -> dict:
        return {
            "generator": "mavnav simulate",
            "scenario": self.scenario.name,
            "seed": self.seed,
            "clock": "onset_s/end_s: scenario time = first boot's vehicle clock, continued through reboots",
            "boot_time_at_start_s": self.scenario.boot_time_at_start_s,
            "start_unix_s": self.scenario.link.start_unix_s,
            "faults": list(self.faults),
        }

    def write(self, tlog_path: Union[str, Path], truth_path: Union[str, Path, None] = None) -> None:
        """Write the tlog, the fault sidecar beside it, and optionally the truth CSV."""
        Path(tlog_path).write_bytes(self.tlog)
        write_sidecar(sidecar_path(tlog_path), self.sidecar())
        if truth_path is not None:
            self.truth.to_csv(truth_path)


# ---------------------------------------------------------------- helpers


def _sample_times(rate_hz: float, duration_s: float, rng: np.random.Generator, jitter: float) -> np.ndarray:
    period = 1.0 / rate_hz
    phase = rng.uniform(0.0, period)
    n = int(math.floor((duration_s - phase) / period)) + 1
    t = phase + np.arange(max(n, 0)) * period
    if jitter > 0 and t.size:
        t = t + rng.uniform(-jitter, jitter, t.size) * period
    return t[(t >= 0.0) & (t < duration_s)]


def _hold_values(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Within each run of ``mask``, replace values by the last value before the run."""
    out = values.copy()
    n = values.shape[0]
    if not mask.any():
        return out
    idx = np.arange(n)
    src = np.where(mask, -1, idx)
    src = np.maximum.accumulate(src)
    first_true = int(np.argmax(mask))
    # runs at the very start hold the first in-window value
    src = np.where(src < 0, first_true, src)
    out[mask] = values[src[mask]]
    return out


def _kin_arrays(k: Kinematics):
    acc_n = np.stack([k.acc_n_mps2, k.acc_e_mps2, -k.acc_up_mps2], axis=1)
    return acc_n, mat_nb(k.roll_rad, k.pitch_rad, k.yaw_rad)


# ---------------------------------------------------------------- main entry


@dataclass
class _Run:
    """One simulation's inputs and its per-message streams, as the steps below fill them."""

    scn: Scenario
    seed: int
    traj: TruthTrajectory
    streams: Dict[str, dict]

    @property
    def off(self) -> float:  # scenario time of simulation time 0
        return self.scn.boot_time_at_start_s

    @property
    def faults(self) -> Sequence[Fault]:
        return self.scn.faults

    def sc(self, name: str) -> np.ndarray:
        """Scenario-clock times of a stream."""
        return self.streams[name]["t_sim"] + self.off


def _message_streams(scn: Scenario, seed: int) -> Dict[str, dict]:
    """Sample times per message type, in simulation time."""
    rates = scn.rates()
    rng_t = _rng(seed, _S_TIMES)
    streams: Dict[str, dict] = {}
    for name in MESSAGE_TYPES:
        r = rates[name]
        if r > 0:
            jitter = scn.link.sample_jitter if name not in ("HEARTBEAT", "SYSTEM_TIME", "HOME_POSITION") else 0.0
            t = _sample_times(r, scn.duration_s, rng_t, jitter)
            if t.size:
                streams[name] = {"t_sim": t, "interval_s": 1.0 / r}
    return streams


def _imu(r: _Run) -> None:
    """The IMUs: specific force with bias, noise and accelerometer faults, rates, magnetometer."""
    seed, sens, traj, streams, faults = r.seed, r.scn.sensors, r.traj, r.streams, r.faults
    g = sens.ins.gravity_mps2
    for name in IMU_TYPES:
        if name not in streams:
            continue
        s = streams[name]
        k = traj.sample(s["t_sim"])
        acc_n, m_nb = _kin_arrays(k)
        bias_up = np.full(s["t_sim"].size, sens.ins.bias_up_mps2)
        for f in faults:
            if f.kind == "accel_bias_step":
                bias_up = bias_up + additive_offset(f, r.sc(name))
        rng = _rng(seed, _S_IMU[name])
        q = accel_noise_std(sens.ins.sigma_a_mps2, sens.ins.alpha_a_per_s, s["interval_s"])
        s["f_b"] = specific_force_body(m_nb, acc_n, g, bias_up, q, sens.ins.body_bias_mps2, rng)
        p, qq, rr = body_rates(k.roll_rad, k.pitch_rad, k.roll_rate_radps, k.pitch_rate_radps, k.yaw_rate_radps)
        gyro = np.stack([p, qq, rr], axis=1)
        if sens.ins.gyro_sigma_radps > 0:
            gyro = gyro + sens.ins.gyro_sigma_radps * rng.standard_normal(gyro.shape)
        s["gyro"] = gyro
        s["mag_gauss"] = np.einsum("kji,j->ki", m_nb, MAG_NED_GAUSS)
        s["temperature_c"] = IMU_TEMPERATURE_C
        s["noise_std_mps2"] = q


def _baro(r: _Run) -> dict:
    """Barometer: samples at SCALED_PRESSURE times (else an internal 25 Hz grid)."""
    seed, sens, traj, streams, faults, off, scn = r.seed, r.scn.sensors, r.traj, r.streams, r.faults, r.off, r.scn
    dur = scn.duration_s
    if "SCALED_PRESSURE" in streams:
        t_baro = streams["SCALED_PRESSURE"]["t_sim"]
    else:
        t_baro = np.arange(0.0, dur, 1.0 / 25.0)
    rng_b = _rng(seed, _S_BARO)
    kb = traj.sample(t_baro)
    u = gauss_markov(t_baro, sens.baro.sigma_bb_m, sens.baro.gamma_bb_per_s, rng_b)
    h_baro = kb.height_m + sens.baro.bias_m + u
    for f in faults:
        if f.kind in ("baro_step", "baro_ramp"):
            h_baro = h_baro + additive_offset(f, t_baro + off)
    for f in faults:
        if f.kind == "baro_freeze":
            h_baro = _hold_values(h_baro, window_mask(f, t_baro + off))
    p_baro = pressure_from_height(h_baro, scn.home.alt_msl_m)
    temp_baro = sens.baro.temperature_c + 0.0 * t_baro
    baro = {"t_sim": t_baro, "height_m": h_baro, "noise_m": u, "pressure_pa": p_baro}
    if "SCALED_PRESSURE" in streams:
        s = streams["SCALED_PRESSURE"]
        s["pressure_pa"] = p_baro
        s["baro_height_m"] = h_baro
        s["baro_noise_m"] = u
        s["temperature_c"] = temp_baro
    if "HIGHRES_IMU" in streams:
        s = streams["HIGHRES_IMU"]
        j = hold_latest(t_baro, s["t_sim"])
        have = j >= 0
        jj = np.maximum(j, 0)
        s["pressure_pa"] = np.where(have, p_baro[jj], 0.0)
        s["pressure_alt_m"] = np.where(have, isa_altitude_m(np.where(have, p_baro[jj], 1e5)), 0.0)
        new = have & (np.concatenate([[True], j[1:] != j[:-1]]))
        # fields_updated: acc|gyro|mag (0x1FF), plus abs_pressure|pressure_alt|temperature on a new baro sample
        s["fields_updated"] = np.where(new, 0x1FF | 0x200 | 0x800 | 0x1000, 0x1FF).astype(np.int64)
        s["temperature_c"] = np.full(s["t_sim"].size, IMU_TEMPERATURE_C)

    return baro


def _gnss(r: _Run) -> None:
    seed, traj, streams, off, scn = r.seed, r.traj, r.streams, r.off, r.scn
    if "GPS_RAW_INT" not in streams:
        return
    s = streams["GPS_RAW_INT"]
    t = s["t_sim"]
    kg = traj.sample(t)
    gc = scn.sensors.gnss
    white = gc.sigma_z_m * _rng(seed, _S_GNSS_WHITE).standard_normal(t.size)
    corr = gauss_markov(t, gc.correlated_sigma_m, 1.0 / gc.correlated_tau_s, _rng(seed, _S_GNSS_GM))
    alt = scn.home.alt_msl_m + kg.height_m + white + corr
    n = t.size
    fix = np.full(n, gc.fix_type, dtype=np.int64)
    sats = np.full(n, gc.satellites, dtype=np.int64)
    v_acc_m = gc.v_acc_m if gc.v_acc_m is not None else math.hypot(gc.sigma_z_m, gc.correlated_sigma_m)
    v_acc = np.full(n, int(round(max(v_acc_m, 0.001) * 1000)), dtype=np.int64)
    h_acc = np.full(n, int(round(max(0.6 * v_acc_m, 0.001) * 1000)), dtype=np.int64)
    eph = np.full(n, 70, dtype=np.int64)
    epv = np.full(n, 110, dtype=np.int64)
    pos_n, pos_e = kg.pos_n_m.copy(), kg.pos_e_m.copy()
    s["gnss_error_m"] = white + corr
    alt = _gnss_offsets(r, alt, t + off)
    s["sent"] = np.ones(n, dtype=bool)
    for f in r.faults:
        if f.kind == "gnss_dropout":
            m = window_mask(f, t + off)
            if f.effective_mode == "silent":
                s["sent"] &= ~m
            else:
                alt = _hold_values(alt, m)
                pos_n, pos_e = _hold_values(pos_n, m), _hold_values(pos_e, m)
                fix[m], sats[m] = 1, 3
                v_acc[m], h_acc[m] = 99999, 99999
                eph[m], epv[m] = 9999, 9999
    s.update(
        alt_msl_m=alt, fix_type=fix, satellites=sats, v_acc_mm=v_acc, h_acc_mm=h_acc, eph=eph, epv=epv,
        pos_n_m=pos_n, pos_e_m=pos_e,
        ground_speed_mps=np.hypot(kg.vel_n_mps, kg.vel_e_mps),
        cog_deg=np.degrees(np.arctan2(kg.vel_e_mps, kg.vel_n_mps)) % 360.0,
    )


def _gnss_offsets(r: _Run, alt: np.ndarray, t_scn: np.ndarray) -> np.ndarray:
    """The GNSS altitude with the step, ramp and noise faults added."""
    for fi, f in enumerate(r.faults):
        if f.kind in ("gnss_step", "gnss_ramp"):
            alt = alt + additive_offset(f, t_scn)
        elif f.kind == "gnss_noise":
            m = window_mask(f, t_scn)
            alt = alt + np.where(m, height_error_m(f, t_scn, _rng(r.seed, _S_FAULT + fi)), 0.0)
    return alt


def _rangefinder(r: _Run) -> dict:
    """Rangefinder: samples at DISTANCE_SENSOR times (else RANGEFINDER's)."""
    seed, traj, streams, off, scn = r.seed, r.traj, r.streams, r.off, r.scn
    rng_primary = "DISTANCE_SENSOR" if "DISTANCE_SENSOR" in streams else ("RANGEFINDER" if "RANGEFINDER" in streams else None)
    if rng_primary is None:
        return {}
    rf = scn.sensors.rangefinder
    t_r = streams[rng_primary]["t_sim"]
    kr = traj.sample(t_r)
    cos_tilt = np.cos(kr.roll_rad) * np.cos(kr.pitch_rad)
    agl = kr.height_m
    if scn.terrain:
        agl = np.maximum(agl - ground_height_m(scn.terrain, t_r + off), 0.0)
    slant = agl / cos_tilt
    reading = slant + rf.sigma_m * _rng(seed, _S_RNG).standard_normal(t_r.size)
    valid = (reading >= rf.min_m) & (reading <= rf.max_m)
    reading = np.where(valid, reading, np.clip(reading, rf.min_m - 0.01, rf.max_m + 0.01))
    quality = np.where(valid, rf.quality, rf.out_of_range_quality).astype(np.int64)
    reading, quality, silent = _rangefinder_faults(r, t_r + off, reading, quality)
    for name in ("DISTANCE_SENSOR", "RANGEFINDER"):
        if name not in streams:
            continue
        s = streams[name]
        j = np.maximum(hold_latest(t_r, s["t_sim"]), 0)
        s["range_m"] = reading[j]
        s["quality"] = quality[j]
        s["sent"] = ~silent[j]
        s["slant_true_m"] = slant[j]
    return {"t_sim": t_r, "range_m": reading, "quality": quality, "slant_true_m": slant}


def _rangefinder_faults(r: _Run, t_scn: np.ndarray, reading: np.ndarray, quality: np.ndarray):
    """(reading, quality, silent) with the rangefinder faults applied."""
    rf = r.scn.sensors.rangefinder
    silent = np.zeros(t_scn.size, dtype=bool)
    for fi, f in enumerate(r.faults):
        m = window_mask(f, t_scn)
        if f.kind == "rng_dropout":
            if f.effective_mode == "silent":
                silent |= m
            else:
                reading = np.where(m, rf.max_m + 0.01, reading)
                quality = np.where(m, 1, quality)
        elif f.kind == "rng_stuck":
            if f.magnitude is None:
                reading = _hold_values(reading, m)
                quality = _hold_values(quality, m)
            else:
                reading = np.where(m, f.magnitude, reading)
                quality = np.where(m, rf.quality, quality)
        elif f.kind == "rng_spikes":
            hit = m & spikes(f, _rng(r.seed, _S_FAULT + fi), t_scn.size)
            reading = np.where(hit, reading + f.magnitude, reading)
        elif f.kind == "rng_out_of_range":
            reading = np.where(m, out_of_range_reading_m(f, rf.max_m), reading)
    return reading, quality, silent


def _attitude(r: _Run) -> None:
    """ATTITUDE and ATTITUDE_QUATERNION: truth plus noise."""
    seed, sens, traj, streams = r.seed, r.scn.sensors, r.traj, r.streams
    rng_a = _rng(seed, _S_ATT)
    for name in ("ATTITUDE", "ATTITUDE_QUATERNION"):
        if name not in streams:
            continue
        s = streams[name]
        ka = traj.sample(s["t_sim"])
        n = s["t_sim"].size
        sa = sens.attitude.sigma_rad
        roll = ka.roll_rad + sa * rng_a.standard_normal(n)
        pitch = ka.pitch_rad + sa * rng_a.standard_normal(n)
        yaw = ka.yaw_rad + sa * rng_a.standard_normal(n)
        yaw = (yaw + np.pi) % (2 * np.pi) - np.pi
        p, qq, rr = body_rates(ka.roll_rad, ka.pitch_rad, ka.roll_rate_radps, ka.pitch_rate_radps, ka.yaw_rate_radps)
        rates_b = np.stack([p, qq, rr], axis=1) + sens.ins.gyro_sigma_radps * rng_a.standard_normal((n, 3))
        s["euler"] = np.stack([roll, pitch, yaw], axis=1)
        s["rates"] = rates_b
        if name == "ATTITUDE_QUATERNION":
            s["quat"] = np.array([frames.quat_from_euler(a, b, c) for a, b, c in zip(roll, pitch, yaw)])


def _estimate(r: _Run) -> None:
    """The autopilot's own estimate: truth + slow Gauss-Markov error (10 Hz grid)."""
    seed, sens, traj, streams, dur = r.seed, r.scn.sensors, r.traj, r.streams, r.scn.duration_s
    est_names = [nm for nm in ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED") if nm in streams]
    if est_names:
        t_grid = np.arange(0.0, dur + 0.1, 0.1)
        e_grid = gauss_markov(t_grid, sens.estimate.sigma_m, 1.0 / sens.estimate.tau_s, _rng(seed, _S_EST))
        for name in est_names:
            s = streams[name]
            ke = traj.sample(s["t_sim"])
            err = np.interp(s["t_sim"], t_grid, e_grid)
            s.update(
                height_m=ke.height_m + err, vel_up_mps=ke.vel_up_mps, pos_n_m=ke.pos_n_m, pos_e_m=ke.pos_e_m,
                vel_n_mps=ke.vel_n_mps, vel_e_mps=ke.vel_e_mps, yaw_rad=ke.yaw_rad, estimate_error_m=err,
            )


def _sent_and_received(r: _Run) -> None:
    """Which messages are sent (reboots, rate drops, silent dropouts) and received (link losses)."""
    off, faults = r.off, r.faults
    for name, s in r.streams.items():
        t = s["t_sim"]
        sent = s.get("sent", np.ones(t.size, dtype=bool)).copy()
        recv = np.ones(t.size, dtype=bool)
        for f in faults:
            m = window_mask(f, t + off)
            if f.kind == "reboot":
                sent &= ~m
            elif f.kind == "link_loss":
                recv &= ~m
            elif f.kind == "rate_drop" and name != "HEARTBEAT" and (f.messages is None or name in f.messages):
                j = np.cumsum(m) - 1  # index within the window
                sent &= ~(m & ~keeps(f, j))
        s["sent"] = sent
        s["received"] = sent & recv


def _link(r: _Run, clock: Clock) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clock, sequence numbers, receive times and global order: fills each stream's
    ``boot``, ``t_vehicle_s``, ``recv_unix_us`` and ``seq``; returns the global
    order's message types and indices, and whether each is received."""
    scn, seed, streams = r.scn, r.seed, r.streams
    names = list(MESSAGE_TYPES)
    present = [nm for nm in names if nm in streams]
    all_t = np.concatenate([streams[nm]["t_sim"] for nm in present]) if present else np.zeros(0)
    all_type = np.concatenate([np.full(streams[nm]["t_sim"].size, names.index(nm)) for nm in present]) if present else np.zeros(0, int)
    all_idx = np.concatenate([np.arange(streams[nm]["t_sim"].size) for nm in present]) if present else np.zeros(0, int)
    all_sent = np.concatenate([streams[nm]["sent"] for nm in present]) if present else np.zeros(0, bool)
    all_recv = np.concatenate([streams[nm]["received"] for nm in present]) if present else np.zeros(0, bool)
    order = np.lexsort((all_type, all_t))
    t_o, sent_o, recv_o = all_t[order], all_sent[order], all_recv[order]
    boot_o = clock.boot(t_o)
    # seq: count of sent messages before this one within the same boot
    csum = np.cumsum(sent_o) - sent_o
    first_of_boot = np.concatenate([[True], boot_o[1:] != boot_o[:-1]]) if t_o.size else np.zeros(0, bool)
    base = np.maximum.accumulate(np.where(first_of_boot, csum, 0)) if t_o.size else csum
    seq_o = ((csum - base) % 256).astype(np.int64)
    # receive time: FIFO link, latency + exponential jitter, never decreasing
    rng_l = _rng(seed, _S_LINK)
    lat = scn.link.latency_s + (rng_l.exponential(scn.link.latency_jitter_s, t_o.size) if scn.link.latency_jitter_s > 0 else 0.0)
    recv_s = t_o + lat
    recv_s = np.where(recv_o, recv_s, -np.inf)
    recv_s = np.maximum.accumulate(recv_s)
    start_us = int(round(scn.link.start_unix_s * 1e6))
    recv_us_o = start_us + np.floor(recv_s * 1e6).astype(np.int64)
    # back to per-type arrays
    type_o, idx_o = all_type[order], all_idx[order]
    seq_by, recv_by, boot_by, tv_by = {}, {}, {}, {}
    for nm in present:
        ti = names.index(nm)
        sel = type_o == ti
        n = streams[nm]["t_sim"].size
        a = np.zeros(n, dtype=np.int64)
        a[idx_o[sel]] = seq_o[sel]
        seq_by[nm] = a
        b = np.zeros(n, dtype=np.int64)
        b[idx_o[sel]] = recv_us_o[sel]
        recv_by[nm] = b
        boot_by[nm] = clock.boot(streams[nm]["t_sim"])
        tv_by[nm] = clock.vehicle_time(streams[nm]["t_sim"])
        streams[nm]["boot"] = boot_by[nm]
        streams[nm]["t_vehicle_s"] = tv_by[nm]
        streams[nm]["recv_unix_us"] = recv_by[nm]
        streams[nm]["seq"] = seq_by[nm]
    return type_o, idx_o, recv_o


def _fault_descriptions(faults: Sequence[Fault], clock: Clock, off: float) -> List[dict]:
    """The sidecar's fault entries, with onsets in simulation and vehicle time."""
    fault_desc = []
    for f in faults:
        d = describe_fault(f)
        on_sim = f.onset_s - off
        d["onset_sim_s"] = on_sim
        d["boot_at_onset"] = int(clock.boot(np.array([on_sim]))[0])
        d["onset_vehicle_s"] = float(clock.vehicle_time(np.array([on_sim]))[0])
        fault_desc.append(d)
    return fault_desc


def simulate(scenario: Scenario, seed: Optional[int] = None, *, encode: bool = True) -> SimResult:
    """Simulate ``scenario`` with ``seed`` (default: the scenario's).

    Returns a :class:`SimResult` with the tlog bytes (empty when ``encode`` is
    False), the truth table, the fault windows and the per-message streams.
    """
    t_start = time.perf_counter()
    scn = scenario
    seed = scn.seed if seed is None else int(seed)
    off = scn.boot_time_at_start_s
    traj = TruthTrajectory(scn)
    faults: Sequence[Fault] = scn.faults
    reboots = sorted((f for f in faults if f.kind == "reboot"), key=lambda f: f.onset_s)
    clock = Clock(off, tuple(f.onset_s - off for f in reboots))

    r = _Run(scn, seed, traj, _message_streams(scn, seed))
    _imu(r)
    baro = _baro(r)
    _gnss(r)
    rng_series = _rangefinder(r)
    _attitude(r)
    _estimate(r)
    _sent_and_received(r)
    t_models = time.perf_counter()

    type_o, idx_o, keep = _link(r, clock)
    tlog = b""
    if encode:
        tlog = encode_tlog(scn, r.streams, type_o[keep], idx_o[keep])
    t_enc = time.perf_counter()

    truth = _truth_table(scn, traj, clock, faults)
    fault_desc = _fault_descriptions(faults, clock, off)
    t_end = time.perf_counter()
    n_rec = int(keep.sum())
    return SimResult(
        scenario=scn,
        seed=seed,
        tlog=tlog,
        truth=truth,
        faults=tuple(fault_desc),
        streams=r.streams,
        trajectory=traj,
        clock=clock,
        timings_s={
            "models": t_models - t_start,
            "encode": t_enc - t_models,
            "truth": t_end - t_enc,
            "total": t_end - t_start,
            "records": float(n_rec),
        },
        series={"baro": baro, "rangefinder": rng_series},
    )


TRUTH_COLUMNS = (
    "t_s",
    "boot",
    "t_sim_s",
    "true_height_ref_m",
    "true_alt_msl_m",
    "true_vel_up_mps",
    "true_acc_up_mps2",
    "true_roll_rad",
    "true_pitch_rad",
    "true_yaw_rad",
    "true_range_agl_m",
    "true_baro_bias_m",
    "true_accel_bias_up_mps2",
    "fault_active",
    "fault_kind",
    "fault_source",
    "true_ground_ref_m",
)


def _truth_table(scn: Scenario, traj: TruthTrajectory, clock: Clock, faults: Sequence[Fault]) -> Truth:
    step = 1.0 / scn.truth_rate_hz
    t = np.arange(0, int(math.floor(scn.duration_s / step + 1e-9)) + 1) * step
    k = traj.sample(t)
    m = mat_nb(k.roll_rad, k.pitch_rad, k.yaw_rad)
    # vertical share of a body-frame bias: f_up = -(R_nb b_b)_down
    body_up = -np.einsum("kj,j->k", m[:, 2, :], np.asarray(scn.sensors.ins.body_bias_mps2, dtype=float))
    active, kinds, sources = active_labels(faults, t + scn.boot_time_at_start_s)
    ground = ground_height_m(scn.terrain, t + scn.boot_time_at_start_s)
    cols = {
        "t_s": clock.vehicle_time(t),
        "boot": clock.boot(t),
        "t_sim_s": t,
        "true_height_ref_m": k.height_m,
        "true_alt_msl_m": scn.home.alt_msl_m + k.height_m,
        "true_vel_up_mps": k.vel_up_mps,
        "true_acc_up_mps2": k.acc_up_mps2,
        "true_roll_rad": k.roll_rad,
        "true_pitch_rad": k.pitch_rad,
        "true_yaw_rad": k.yaw_rad,
        "true_range_agl_m": np.maximum(k.height_m - ground, 0.0),  # vertical height above the ground below
        "true_baro_bias_m": np.full(t.size, scn.sensors.baro.bias_m),
        "true_accel_bias_up_mps2": scn.sensors.ins.bias_up_mps2 + body_up,
        "fault_active": active,
        "fault_kind": np.array(kinds, dtype=object),
        "fault_source": np.array(sources, dtype=object),
        "true_ground_ref_m": ground,  # ground height above the reference under the vehicle (terrain)
    }
    return Truth(cols)


def write_truth_csv(path: Union[str, Path], cols: Dict[str, np.ndarray]) -> None:
    fmt = {
        "t_s": "{:.6f}",
        "boot": "{:d}",
        "t_sim_s": "{:.6f}",
        "fault_active": "{:d}",
        "fault_kind": "{}",
        "fault_source": "{}",
    }
    lists = [cols[c].tolist() for c in TRUTH_COLUMNS]
    fmts = [fmt.get(c, "{:.5f}") for c in TRUTH_COLUMNS]
    lines: List[str] = [",".join(TRUTH_COLUMNS)]
    for row in zip(*lists):
        lines.append(",".join(f.format(v) for f, v in zip(fmts, row)))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_truth_csv(path: Union[str, Path]) -> Dict[str, np.ndarray]:
    """Read a truth CSV written by :func:`write_truth_csv` back into arrays."""
    text = Path(path).read_text(encoding="utf-8").splitlines()
    header = text[0].split(",")
    rows = [line.split(",") for line in text[1:] if line]
    out: Dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] for r in rows]
        if name in ("fault_kind", "fault_source"):
            out[name] = np.array(col, dtype=object)
        elif name in ("boot", "fault_active"):
            out[name] = np.array([int(v) for v in col], dtype=np.int64)
        else:
            out[name] = np.array([float(v) for v in col])
    return out
