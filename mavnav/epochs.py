"""Turn time-stamped samples into filter epochs.

An *epoch* is the end of one filter step. Epochs fall on barometer samples
(the measurement every channel shares), so the baro differencing of
MODEL.md section 4 always pairs consecutive baro samples. Between two epochs
the vertical specific force is integrated with a zero-order hold (each IMU
sample holds until the next one), giving the control increments ``dp_m`` and
``dv_mps`` of ``f_up - g``; with one IMU sample per epoch these are exactly the
paper's ``Psi W``.

GNSS and rangefinder samples are used at the first epoch at or after their
time, with their age (``AuxMeasurement.age_s``): at each epoch the newest
pending sample not after it is used (older ones are counted as superseded)
and samples newer than the epoch wait for the next one. They queue: a
stream that runs slightly ahead of the baro clock at the same rate must not
replace each sample before it can be used.

Gaps: when no baro sample comes for ``max_epoch_gap_s`` of IMU time, an epoch
is forced at the IMU time without a baro row and the differencing restarts at
the next baro sample. A baro sample that waits for IMU data longer than
``max_epoch_gap_s`` is processed with the last IMU value held (counted as
``imu_stale_epochs``).

Pure: no clock, no I/O. ``push(sample)`` returns the epochs it completed.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass
from typing import Optional, Union

from .channel import AuxMeasurement, EpochInputs
from .config import Config
from .samples import BaroHeight, GnssHeight, RangeHeight, Reboot, SpecificForceUp


@dataclass(frozen=True, slots=True)
class EpochStart:
    """The first epoch of a run (or after a reboot): channels initialise here."""

    t_us: int
    baro_m: float


Epoch = Union[EpochStart, EpochInputs]


class EpochBuilder:
    """Samples in, epochs out. One instance per vehicle and boot."""

    def __init__(self, cfg: Config):
        f = cfg.filter
        self._g = f.gravity_mps2
        self._max_gap_us = int(round(f.max_epoch_gap_s * 1e6))
        self._max_latency_us = int(round(f.max_meas_latency_s * 1e6))
        self._gnss_cfg = cfg.sensors.gnss
        self._rng_sigma = cfg.sensors.rangefinder.sigma_m
        self._rng_scale = cfg.sensors.rangefinder.scale_sigma_frac
        self.counters: Counter[str] = Counter()
        self.reset()

    def reset(self) -> None:
        self._imu: deque[tuple[int, float]] = deque()  # (t_us, f_up) not yet fully integrated
        self._last_imu_t: Optional[int] = None
        self._epoch_t: Optional[int] = None  # None until started
        self._pending_baro: deque[BaroHeight] = deque()
        self._aux: dict[str, deque] = {"gnss": deque(), "rng": deque()}
        self._baro_restart = False

    @property
    def started(self) -> bool:
        return self._epoch_t is not None

    # ------------------------------------------------------------------ push

    def push(self, s) -> list[Epoch]:
        if isinstance(s, SpecificForceUp):
            return self._on_imu(s.t_us, s.f_up_mps2)
        if isinstance(s, BaroHeight):
            return self._on_baro(s)
        if isinstance(s, GnssHeight):
            self._on_aux(s, "gnss")
            return []
        if isinstance(s, RangeHeight):
            self._on_aux(s, "rng")
            return []
        if isinstance(s, Reboot):
            self.reset()
            self.counters["reboot_resets"] += 1
        return []

    def _on_imu(self, t_us: int, f_up: float) -> list[Epoch]:
        if self._last_imu_t is not None and t_us <= self._last_imu_t:
            self.counters["imu_not_increasing"] += 1
            return []
        self._imu.append((t_us, f_up))
        self._last_imu_t = t_us
        out: list[Epoch] = []
        if not self.started:
            while len(self._imu) > 1:
                self._imu.popleft()  # keep only the latest until the first baro
            return out
        while self._pending_baro and self._pending_baro[0].t_us <= t_us:
            out.append(self._epoch_at(self._pending_baro.popleft()))
        if not self._pending_baro and t_us - self._epoch_t > self._max_gap_us:
            out.append(self._forced_epoch(t_us))
        return out

    def _on_baro(self, b: BaroHeight) -> list[Epoch]:
        if not self.started:
            if self._last_imu_t is None:
                self.counters["baro_before_imu"] += 1
                return []
            self._epoch_t = b.t_us
            self._baro_restart = False
            self.counters["starts"] += 1
            return [EpochStart(t_us=b.t_us, baro_m=b.height_ref_m)]
        last_t = self._pending_baro[-1].t_us if self._pending_baro else self._epoch_t
        if b.t_us <= last_t:
            self.counters["baro_late"] += 1
            return []
        self._pending_baro.append(b)
        out: list[Epoch] = []
        # Ready when IMU data covers it; or held IMU when the IMU has gone quiet.
        while self._pending_baro:
            head = self._pending_baro[0]
            if head.t_us <= self._last_imu_t:
                out.append(self._epoch_at(self._pending_baro.popleft()))
            elif b.t_us - self._last_imu_t > self._max_gap_us:
                self.counters["imu_stale_epochs"] += 1
                out.append(self._epoch_at(self._pending_baro.popleft()))
            else:
                break
        return out

    def _on_aux(self, s, which: str) -> None:
        if not self.started:
            self.counters[f"{which}_before_start"] += 1
            return
        if s.t_us < self._epoch_t - self._max_latency_us:
            self.counters[f"{which}_late"] += 1
            return
        q = self._aux[which]
        if len(q) >= 64:  # bounded: a stream far ahead of the baro clock
            q.popleft()
            self.counters[f"{which}_superseded"] += 1
        q.append(s)

    # ------------------------------------------------------------------ epochs

    def _integrate_to(self, t_end: int) -> tuple[float, float]:
        """Zero-order-hold integral of f_up - g from the last epoch to ``t_end``."""
        g = self._g
        t = self._epoch_t
        dp = dv = 0.0
        imu = self._imu
        # imu[0] holds at t (its time is <= t); later samples take over in turn.
        while True:
            f = imu[0][1]
            nxt = imu[1][0] if len(imu) > 1 else None
            seg_end = t_end if nxt is None or nxt > t_end else nxt
            tau = (seg_end - t) * 1e-6
            a = f - g
            dp += dv * tau + 0.5 * a * tau * tau
            dv += a * tau
            t = seg_end
            if nxt is not None and nxt <= t_end:
                imu.popleft()
                if nxt == t_end:
                    break
            else:
                break
        return dp, dv

    def _aux_for(self, which: str, t_us: int) -> Optional[AuxMeasurement]:
        q = self._aux[which]
        s = None
        while q and q[0].t_us <= t_us:
            if s is not None:
                self.counters[f"{which}_superseded"] += 1
            s = q.popleft()
        if s is None:
            return None
        age_us = t_us - s.t_us
        if age_us > self._max_latency_us:
            self.counters[f"{which}_late"] += 1
            return None
        if which == "gnss":
            c = self._gnss_cfg
            if c.use_v_acc and s.sigma_m is not None:
                sigma = max(s.sigma_m, c.v_acc_floor_m)
            else:
                sigma = c.sigma_z_m
            return AuxMeasurement(height_m=s.height_ref_m, sigma_m=sigma, age_s=age_us * 1e-6)
        h = s.height_agl_m
        sigma = math.hypot(self._rng_sigma, self._rng_scale * h) if self._rng_scale else self._rng_sigma
        return AuxMeasurement(height_m=h, sigma_m=sigma, age_s=age_us * 1e-6)

    def _make(self, t_us: int, baro_m: Optional[float]) -> EpochInputs:
        dp, dv = self._integrate_to(t_us)
        dt = (t_us - self._epoch_t) * 1e-6
        restart = self._baro_restart and baro_m is not None
        ep = EpochInputs(
            t_us=t_us,
            dt_s=dt,
            dp_m=dp,
            dv_mps=dv,
            baro_m=baro_m,
            gnss=self._aux_for("gnss", t_us),
            rng=self._aux_for("rng", t_us),
            baro_restart=restart,
        )
        self._epoch_t = t_us
        return ep

    def _epoch_at(self, b: BaroHeight) -> EpochInputs:
        ep = self._make(b.t_us, b.height_ref_m)
        if ep.baro_restart:
            self.counters["baro_restarts"] += 1
        self._baro_restart = False
        return ep

    def _forced_epoch(self, t_us: int) -> EpochInputs:
        self.counters["forced_epochs"] += 1
        self._baro_restart = True
        return self._make(t_us, None)
