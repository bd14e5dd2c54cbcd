"""Scenario schema for the simulator: typed, frozen, unknown keys refused by name.

A scenario names a trajectory, an autopilot profile (which messages, at what
rates), the true sensor errors and a list of faults. The noise quantities the
filter models too are the filter's own keys, inherited from the *Noise
sections of :mod:`mavnav.config` (``ins.sigma_a_mps2``, ``ins.alpha_a_per_s``,
``baro.sigma_bb_m``, ``baro.gamma_bb_per_s``, ``gnss.sigma_z_m``,
``rangefinder.sigma_m``; ``ins.gravity_mps2`` is ``filter.gravity_mps2``'s),
with the same bounds but the truth's own defaults, and a noise of 0 allowed
(a noise-free sensor): the truth must stay free to differ from the model. The
true biases and the extra realism (GNSS correlated error, rangefinder
limits...) are added here.

Times are *scenario time*: seconds of the first boot's vehicle clock
(``time_boot_ms``), which continues as if no reboot happened. With the default
``boot_time_at_start_s: 0`` scenario time is also simulation time.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Dict, List, Literal, Optional, Tuple, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..config import (
    BaroConfig,
    BaroNoise,
    FilterConfig,
    GnssConfig,
    GnssNoise,
    InsConfig,
    InsNoise,
    RangefinderConfig,
    RangefinderNoise,
    SensorsConfig,
    describe_error,
    read_yaml,
    truth_field,
    validation_error,
)
from ..errors import ConfigError
from ..sensors import BARO_INS, GNSS, INPUT, RANGEFINDER, Sensor


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


# ---------------------------------------------------------------- trajectory


class AttitudeMotion(_Section):
    """Roll/pitch/yaw excursions (sinusoids) so the IMU must be rotated.

    Roll and pitch fade to level on the ground (below 1 m); yaw does not.
    """

    roll_amplitude_deg: float = Field(6.0, ge=0, le=60)
    roll_period_s: float = Field(7.0, gt=0)
    pitch_amplitude_deg: float = Field(5.0, ge=0, le=60)
    pitch_period_s: float = Field(11.0, gt=0)
    pitch_offset_deg: float = Field(-3.0, ge=-45, le=45)
    yaw_amplitude_deg: float = Field(10.0, ge=0, le=180)
    yaw_period_s: float = Field(40.0, gt=0)


class LandingTrajectory(_Section):
    """Hover at ``start_height_m``, then a glide slope to a touchdown at home."""

    kind: Literal["landing"]
    start_height_m: float = Field(40.0, gt=0)
    hold_s: float = Field(5.0, ge=0)
    glide_slope_deg: float = Field(8.0, gt=0, lt=90)
    descent_speed_mps: float = Field(1.5, gt=0)  # vertical speed on the slope
    blend_s: float = Field(2.0, gt=0)  # smoothing of the start of the descent
    flare_s: float = Field(4.0, gt=0)  # smoothing of the touchdown
    heading_deg: float = 35.0
    attitude: AttitudeMotion = AttitudeMotion()


class HoverTrajectory(_Section):
    """Optional take-off from home, then hover with a slow height wander."""

    kind: Literal["hover"]
    height_m: float = Field(15.0, gt=0)
    takeoff: bool = True  # start on the ground; otherwise start in the hover
    ground_s: float = Field(3.0, ge=0)  # on the ground before the take-off
    climb_speed_mps: float = Field(2.0, gt=0)
    blend_s: float = Field(1.5, gt=0)
    wander_m: float = Field(0.3, ge=0)  # amplitude of a slow height oscillation
    wander_period_s: float = Field(20.0, gt=0)
    horizontal_wander_m: float = Field(2.0, ge=0)
    heading_deg: float = 35.0
    attitude: AttitudeMotion = AttitudeMotion()


class StepsTrajectory(_Section):
    """From ``start_height_m``, climb or descend to each height in turn and hold."""

    kind: Literal["steps"]
    start_height_m: float = Field(0.0, ge=0)
    heights_m: Tuple[float, ...] = Field((10.0, 25.0, 8.0, 0.0), min_length=1)
    hold_s: float = Field(10.0, ge=0)
    vertical_speed_mps: float = Field(2.0, gt=0)
    blend_s: float = Field(1.5, gt=0)
    horizontal_wander_m: float = Field(2.0, ge=0)
    heading_deg: float = 35.0
    attitude: AttitudeMotion = AttitudeMotion()

    @model_validator(mode="after")
    def _heights_not_negative(self) -> "StepsTrajectory":
        if any(h < 0 for h in self.heights_m):
            raise ValueError("heights_m must be >= 0 (ground is at the reference)")
        return self


Trajectory = Annotated[
    Union[LandingTrajectory, HoverTrajectory, StepsTrajectory], Field(discriminator="kind")
]
TRAJECTORY_KINDS = ("landing", "hover", "steps")


# ---------------------------------------------------------------- sensors


class SimInsConfig(InsNoise):
    """Strapdown IMU: MODEL.md eq. 1-2 on the vertical, noise on every axis.

    Per IMU message sample the noise is white with standard deviation
    ``sigma_a_mps2 * sqrt(2 / (alpha_a_per_s * T))``, ``T`` the message's
    nominal interval (the dimensionally consistent form of MODEL.md's erratum).
    """

    sigma_a_mps2: float = truth_field(InsNoise, "sigma_a_mps2", 0.02, zero_ok=True)
    alpha_a_per_s: float = truth_field(InsNoise, "alpha_a_per_s", 1.0)
    bias_up_mps2: float = 0.0  # da: constant bias of the vertical specific force
    body_bias_mps2: Tuple[float, float, float] = (0.0, 0.0, 0.0)  # extra FRD bias
    gyro_sigma_radps: float = Field(0.003, ge=0)
    gravity_mps2: float = truth_field(FilterConfig, "gravity_mps2")


class SimBaroConfig(BaroNoise):
    """Barometer: ``H_baro = H + dH + u``, ``u`` first-order Gauss-Markov."""

    sigma_bb_m: float = truth_field(BaroNoise, "sigma_bb_m", 0.5, zero_ok=True)
    gamma_bb_per_s: float = truth_field(BaroNoise, "gamma_bb_per_s", 1.0)
    bias_m: float = 0.0  # dH
    temperature_c: float = 25.0


class SimGnssConfig(GnssNoise):
    """GNSS altitude: white ``sigma_z_m`` plus a slow Gauss-Markov error."""

    sigma_z_m: float = truth_field(GnssNoise, "sigma_z_m", 0.8, zero_ok=True)
    correlated_sigma_m: float = Field(1.0, ge=0)
    correlated_tau_s: float = Field(300.0, gt=0)
    v_acc_m: Optional[float] = Field(None, gt=0)  # reported; default sqrt(white^2 + correlated^2)
    geoid_separation_m: float = 47.0  # alt_ellipsoid - alt
    fix_type: int = Field(3, ge=2, le=8)
    satellites: int = Field(14, ge=0, le=255)
    time_base: Literal["boot", "unix"] = "boot"  # GPS_RAW_INT.time_usec


class SimRangefinderConfig(RangefinderNoise):
    """Downward rangefinder over the ground (the reference elevation plus ``terrain``).

    A reading outside ``[min_m, max_m]`` is sent just outside the limits
    (``min_m - 0.01`` or ``max_m + 0.01``) with ``signal_quality``
    ``out_of_range_quality``: 1 is MAVLink's "invalid", what ArduPilot sends
    for a sensor that reports a quality (``MAX(quality, 1)``) and what PX4
    sends once its stream maps its own 0 (invalid) to 1; 0 is "unknown", what
    PX4 streams that never set the field and ArduPilot drivers without a
    quality send (with ``quality: 0`` for the in-range readings too): then
    ``current_distance`` against ``min_distance``/``max_distance`` is the only
    sign of an out-of-range reading. ``RANGEFINDER`` carries the distance
    alone.
    """

    sigma_m: float = truth_field(RangefinderNoise, "sigma_m", 0.05, zero_ok=True)
    min_m: float = Field(0.2, ge=0)
    max_m: float = Field(40.0, gt=0)
    quality: int = Field(100, ge=0, le=100)  # DISTANCE_SENSOR.signal_quality when in range
    out_of_range_quality: int = Field(1, ge=0, le=100)  # ... when outside [min_m, max_m]

    @model_validator(mode="after")
    def _range(self) -> "SimRangefinderConfig":
        if self.max_m <= self.min_m:
            raise ValueError("max_m must exceed min_m")
        return self


class SimAttitudeConfig(_Section):
    sigma_rad: float = Field(0.002, ge=0)  # white error of the reported attitude


class SimEstimateConfig(_Section):
    """The autopilot's own height estimate (GLOBAL_POSITION_INT, LOCAL_POSITION_NED)."""

    sigma_m: float = Field(0.15, ge=0)
    tau_s: float = Field(5.0, gt=0)


class SimSensorsConfig(_Section):
    ins: SimInsConfig = SimInsConfig()
    baro: SimBaroConfig = SimBaroConfig()
    gnss: SimGnssConfig = SimGnssConfig()
    rangefinder: SimRangefinderConfig = SimRangefinderConfig()
    attitude: SimAttitudeConfig = SimAttitudeConfig()
    estimate: SimEstimateConfig = SimEstimateConfig()


# ---------------------------------------------------------------- profile


MESSAGE_TYPES = (
    "HEARTBEAT",
    "SYSTEM_TIME",
    "HOME_POSITION",
    "HIGHRES_IMU",
    "RAW_IMU",
    "SCALED_IMU",
    "SCALED_IMU2",
    "ATTITUDE",
    "ATTITUDE_QUATERNION",
    "SCALED_PRESSURE",
    "GPS_RAW_INT",
    "DISTANCE_SENSOR",
    "RANGEFINDER",
    "GLOBAL_POSITION_INT",
    "LOCAL_POSITION_NED",
)

PROFILE_RATES_HZ: Dict[str, Dict[str, float]] = {
    # PX4 in ONBOARD mode: HIGHRES_IMU fast, everything else at telemetry rates.
    "px4": {
        "HEARTBEAT": 1.0,
        "SYSTEM_TIME": 1.0,
        "HOME_POSITION": 0.5,
        "HIGHRES_IMU": 100.0,
        "ATTITUDE": 50.0,
        "SCALED_PRESSURE": 25.0,
        "GPS_RAW_INT": 10.0,
        "DISTANCE_SENSOR": 20.0,
        "GLOBAL_POSITION_INT": 10.0,
        "LOCAL_POSITION_NED": 10.0,
    },
    # ArduPilot stream groups RAW_SENS, EXT_STAT, POSITION, EXTRA1, EXTRA3.
    "ardupilot": {
        "HEARTBEAT": 1.0,
        "SYSTEM_TIME": 1.0,
        "HOME_POSITION": 0.2,
        "RAW_IMU": 10.0,
        "SCALED_IMU2": 10.0,
        "ATTITUDE": 10.0,
        "SCALED_PRESSURE": 10.0,
        "GPS_RAW_INT": 5.0,
        "DISTANCE_SENSOR": 10.0,
        "RANGEFINDER": 10.0,
        "GLOBAL_POSITION_INT": 10.0,
        "LOCAL_POSITION_NED": 10.0,
    },
}

_RateField = Optional[Annotated[float, Field(ge=0, le=1000)]]


class Rates(_Section):
    """Message rates in Hz; unset: the profile's default; 0: not sent."""

    HEARTBEAT: _RateField = None
    SYSTEM_TIME: _RateField = None
    HOME_POSITION: _RateField = None
    HIGHRES_IMU: _RateField = None
    RAW_IMU: _RateField = None
    SCALED_IMU: _RateField = None
    SCALED_IMU2: _RateField = None
    ATTITUDE: _RateField = None
    ATTITUDE_QUATERNION: _RateField = None
    SCALED_PRESSURE: _RateField = None
    GPS_RAW_INT: _RateField = None
    DISTANCE_SENSOR: _RateField = None
    RANGEFINDER: _RateField = None
    GLOBAL_POSITION_INT: _RateField = None
    LOCAL_POSITION_NED: _RateField = None


class Home(_Section):
    alt_msl_m: float = Field(488.0, ge=-400, le=8000)  # reference elevation h_ref
    lat_deg: float = Field(47.397742, ge=-89, le=89)
    lon_deg: float = Field(8.545594, ge=-180, le=180)


class Link(_Section):
    """Vehicle -> ground station: receive time = vehicle time + start + latency."""

    start_unix_s: float = Field(1717236000.0, gt=946684800)  # 2024-06-01T10:00:00Z
    latency_s: float = Field(0.008, ge=0, le=5)
    latency_jitter_s: float = Field(0.004, ge=0, le=5)  # mean of an exponential extra delay
    sample_jitter: float = Field(0.02, ge=0, lt=0.5)  # +-fraction of a message interval
    sysid: int = Field(1, ge=1, le=255)
    compid: int = Field(1, ge=0, le=255)


# ---------------------------------------------------------------- faults


FaultKind = Literal[
    "gnss_step",
    "gnss_ramp",
    "gnss_dropout",
    "gnss_noise",
    "rng_dropout",
    "rng_stuck",
    "rng_spikes",
    "rng_out_of_range",
    "baro_step",
    "baro_ramp",
    "baro_freeze",
    "accel_bias_step",
    "rate_drop",
    "link_loss",
    "reboot",
]

FAULT_SOURCE: Dict[str, Sensor] = {
    "gnss_step": GNSS,
    "gnss_ramp": GNSS,
    "gnss_dropout": GNSS,
    "gnss_noise": GNSS,
    "rng_dropout": RANGEFINDER,
    "rng_stuck": RANGEFINDER,
    "rng_spikes": RANGEFINDER,
    "rng_out_of_range": RANGEFINDER,
    "baro_step": BARO_INS,
    "baro_ramp": BARO_INS,
    "baro_freeze": BARO_INS,
    "accel_bias_step": BARO_INS,
    "rate_drop": INPUT,
    "link_loss": INPUT,
    "reboot": INPUT,
}

# What ``magnitude`` means for each kind (None: not used).
FAULT_MAGNITUDE: Dict[str, Optional[str]] = {
    "gnss_step": "m added to the GNSS altitude",
    "gnss_ramp": "m/s: the GNSS altitude error grows at this rate, then snaps back at the end",
    "gnss_dropout": None,
    "gnss_noise": "m: standard deviation of extra white noise on the GNSS altitude",
    "rng_dropout": None,
    "rng_stuck": "optional m: the stuck reading (default: the last reading before onset)",
    "rng_spikes": "m added to a random fraction `probability` (default 0.3) of readings",
    "rng_out_of_range": "optional m beyond max_distance that the readings report (default 1)",
    "baro_step": "m added to the barometric height (pressure lowered to match)",
    "baro_ramp": "m/s: the barometric height error grows at this rate, then snaps back",
    "baro_freeze": None,
    "accel_bias_step": "m/s^2 added to the vertical specific force",
    "rate_drop": "fraction of messages still sent, 0 < m < 1",
    "link_loss": None,
    "reboot": None,
}
_NEEDS_MAGNITUDE = {k for k, v in FAULT_MAGNITUDE.items() if v and not v.startswith("optional")}
_MODES = {"gnss_dropout": ("nofix", "silent"), "rng_dropout": ("invalid", "silent")}


class Fault(_Section):
    """One fault: from ``onset_s`` (vehicle time) for ``duration_s`` (None: to the end)."""

    kind: FaultKind
    onset_s: float = Field(ge=0)
    duration_s: Optional[float] = Field(None, gt=0)
    magnitude: Optional[float] = None
    probability: Optional[float] = Field(None, gt=0, le=1)  # rng_spikes only
    mode: Optional[Literal["nofix", "silent", "invalid"]] = None  # dropouts only
    messages: Optional[Tuple[str, ...]] = None  # restrict to these message types
    seed: int = 0  # random draws of noise bursts and spikes (inject; simulate uses the scenario seed)
    boot: Optional[int] = Field(None, ge=0)  # inject: the boot (0 = first) in which onset counts

    @model_validator(mode="after")
    def _per_kind(self) -> "Fault":
        k = self.kind
        if k in _NEEDS_MAGNITUDE and self.magnitude is None:
            raise ValueError(f"{k} needs a magnitude ({FAULT_MAGNITUDE[k]})")
        if FAULT_MAGNITUDE[k] is None and self.magnitude is not None:
            raise ValueError(f"{k} takes no magnitude")
        if k == "rate_drop" and not (0.0 < self.magnitude < 1.0):  # type: ignore[operator]
            raise ValueError("rate_drop magnitude is the fraction kept, 0 < m < 1")
        if k == "gnss_noise" and self.magnitude <= 0:  # type: ignore[operator]
            raise ValueError("gnss_noise magnitude is a standard deviation, > 0")
        if k in ("rng_out_of_range",) and self.magnitude is not None and self.magnitude <= 0:
            raise ValueError("rng_out_of_range magnitude must be > 0")
        if self.probability is not None and k != "rng_spikes":
            raise ValueError(f"{k} takes no probability (only rng_spikes)")
        if self.mode is not None and self.mode not in _MODES.get(k, ()):
            allowed = _MODES.get(k)
            raise ValueError(
                f"{k} takes no mode" if not allowed else f"{k} mode must be one of {', '.join(allowed)}"
            )
        if k in ("link_loss", "reboot") and self.duration_s is None:
            raise ValueError(f"{k} needs a duration_s")
        return self

    @property
    def source(self) -> str:
        return FAULT_SOURCE[self.kind]

    @property
    def end_s(self) -> float:
        return float("inf") if self.duration_s is None else self.onset_s + self.duration_s

    @property
    def effective_mode(self) -> Optional[str]:
        if self.mode is not None:
            return self.mode
        return _MODES[self.kind][0] if self.kind in _MODES else None

    @property
    def effective_probability(self) -> float:
        return 0.3 if self.probability is None else self.probability


# ---------------------------------------------------------------- terrain


class TerrainPatch(_Section):
    """Ground ``height_m`` above the reference under the vehicle from ``from_s`` to ``to_s``
    (scenario time, ``from_s <= t < to_s``): a roof, a wall top, a ditch (negative).

    Only the rangefinder sees the ground: it measures height minus ground.
    The edges are sharp (a roof edge passes under the sensor in one sample).
    """

    from_s: float = Field(ge=0)
    to_s: float
    height_m: float = Field(ge=-1000, le=1000)

    @model_validator(mode="after")
    def _order(self) -> "TerrainPatch":
        if self.to_s <= self.from_s:
            raise ValueError("to_s must exceed from_s")
        return self


# ---------------------------------------------------------------- scenario


class Scenario(_Section):
    name: str = "scenario"
    description: str = ""
    duration_s: float = Field(gt=0, le=3600)
    seed: int = Field(1, ge=0)
    profile: Literal["px4", "ardupilot"] = "px4"
    boot_time_at_start_s: float = Field(0.0, ge=0, le=1e6)
    home: Home = Home()
    link: Link = Link()
    rates_hz: Rates = Rates()
    trajectory: Trajectory
    sensors: SimSensorsConfig = SimSensorsConfig()
    faults: Tuple[Fault, ...] = ()
    terrain: Tuple[TerrainPatch, ...] = ()  # ground under the vehicle; none: flat at the reference
    truth_rate_hz: float = Field(10.0, gt=0, le=1000)

    @model_validator(mode="after")
    def _checks(self) -> "Scenario":
        patches = sorted(self.terrain, key=lambda p: p.from_s)
        for a, b in zip(patches, patches[1:]):
            if b.from_s < a.to_s:
                raise ValueError(f"terrain: patches overlap ({a.from_s:g}-{a.to_s:g} s and {b.from_s:g}-{b.to_s:g} s)")
        for i, f in enumerate(self.faults):
            if f.messages is not None and f.kind != "rate_drop":
                raise ValueError(f"faults[{i}].messages: in a scenario only rate_drop takes messages")
            if f.messages is not None:
                bad = [m for m in f.messages if m not in MESSAGE_TYPES]
                if bad:
                    raise ValueError(f"faults[{i}].messages: unknown message type '{bad[0]}'")
            if f.boot is not None:
                raise ValueError(f"faults[{i}].boot: only for inject")
            if f.onset_s < self.boot_time_at_start_s:
                raise ValueError(f"faults[{i}].onset_s is before the scenario starts")
            if f.onset_s >= self.boot_time_at_start_s + self.duration_s:
                raise ValueError(f"faults[{i}].onset_s is after the scenario ends")
        rates = self.rates()
        if not any(rates[m] > 0 for m in ("HIGHRES_IMU", "RAW_IMU", "SCALED_IMU", "SCALED_IMU2")):
            raise ValueError("rates_hz: no IMU message is sent")
        return self

    def filter_sensors(self) -> SensorsConfig:
        """The filter's noise parameters matching this scenario's sensors.

        GNSS: ``sigma_z_m`` is the total (white and correlated) vertical error,
        the same number the simulated receiver reports as ``v_acc``.
        """
        s = self.sensors
        g = s.gnss
        sigma_z = g.v_acc_m if g.v_acc_m is not None else math.hypot(g.sigma_z_m, g.correlated_sigma_m)
        return SensorsConfig(
            ins=InsConfig(sigma_a_mps2=max(s.ins.sigma_a_mps2, 1e-6), alpha_a_per_s=s.ins.alpha_a_per_s),
            baro=BaroConfig(sigma_bb_m=max(s.baro.sigma_bb_m, 1e-6), gamma_bb_per_s=s.baro.gamma_bb_per_s),
            gnss=GnssConfig(sigma_z_m=max(sigma_z, 1e-6)),
            # the simulated rangefinder has white noise only: no scale term
            rangefinder=RangefinderConfig(sigma_m=max(s.rangefinder.sigma_m, 1e-6), scale_sigma_frac=0.0),
        )

    def rates(self) -> Dict[str, float]:
        """Every message type's rate in Hz (0: not sent), profile defaults filled in."""
        base = PROFILE_RATES_HZ[self.profile]
        given = self.rates_hz.model_dump()
        return {m: float(given[m]) if given[m] is not None else base.get(m, 0.0) for m in MESSAGE_TYPES}


# ---------------------------------------------------------------- loading


def _loc(parts) -> str:
    out = ""
    prev = None
    for p in parts:
        if p == "__root__":
            continue
        if prev == "trajectory" and p in TRAJECTORY_KINDS:
            prev = p
            continue  # the discriminator's tag, not a key the user wrote
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            out += ("." if out else "") + str(p)
        prev = p
    return out


def _describe(err: dict) -> str:
    return describe_error(err, _loc(err.get("loc", ())))


def scenario_from_dict(data: object, origin: str = "<dict>") -> Scenario:
    """Validate a plain mapping into a :class:`Scenario` (one-line ConfigError)."""
    if not isinstance(data, dict):
        raise ConfigError(f"{origin}: top level must be a mapping, not {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc, origin, _describe) from None


def load_scenario(path: Union[str, Path]) -> Scenario:
    """Load a scenario YAML file (one-line ConfigError on any failure)."""
    data, origin = read_yaml(path, "scenario")
    return scenario_from_dict(data, origin=origin)



__all__: List[str] = [
    "Scenario",
    "Fault",
    "TerrainPatch",
    "FAULT_SOURCE",
    "FAULT_MAGNITUDE",
    "MESSAGE_TYPES",
    "PROFILE_RATES_HZ",
    "load_scenario",
    "scenario_from_dict",
]
