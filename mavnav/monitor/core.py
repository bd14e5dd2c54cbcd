"""The integrity monitor: samples in, epoch reports and alarm events out.

:class:`Monitor` owns the epoch builder, the channel bank and one decision
logic (:mod:`.paper` or :mod:`.adaptive`). ``push(sample)`` is a pure step of
the fold: time comes only from the samples, nothing is read or written.

Besides the channels, the monitor watches the telemetry itself (source
``input``): link loss, and whether each input's rate supports the
time-to-alarm (an input too slow is reported, with the rate it would need).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from typing import Optional

from ..bank import GNSS, RNG, ChannelBank
from ..channel import EpochInputs, Model
from ..config import Config
from ..epochs import EpochBuilder, EpochStart
from ..report import CHANNEL_NAMES, AlarmEvent, ChannelReport, EpochReport
from ..sensors import AUTOPILOT, INPUT, RANGE_STREAM, RANGEFINDER
# the sensor words (the names GNSS and RNG are the bank's channel indices here)
from ..sensors import BARO as BARO_S, BARO_INS as BARO_INS_S, GNSS as GNSS_S, IMU as IMU_S
from ..samples import (
    AutopilotHeight,
    BaroHeight,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    RangeHeight,
    Reboot,
    ReferenceSet,
    Rejected,
    SpecificForceUp,
)
from .levels import normal_k
from .tracker import SourceTracker

_RATE_WINDOW_US = 5_000_000
RNG_S = RANGEFINDER.short  # "rng": the rangefinder's key in the rates, as a slow input's reason prints it


class RateMeter:
    """Samples per second of vehicle time over a sliding window."""

    def __init__(self) -> None:
        self._q: deque[int] = deque()

    def push(self, t_us: int) -> None:
        q = self._q
        q.append(t_us)
        limit = t_us - _RATE_WINDOW_US
        while q and q[0] <= limit:
            q.popleft()

    def rate_hz(self, now_us: int) -> float:
        """Rate while the input is flowing; 0 when it has gone silent (a gap
        or a dropout is the channels' business, not a slow input)."""
        q = self._q
        while q and q[0] <= now_us - _RATE_WINDOW_US:
            q.popleft()
        if len(q) < 3:
            return 0.0
        span = q[-1] - q[0]
        rate = (len(q) - 1) / (span * 1e-6) if span > 0 else 0.0
        if rate <= 0.0 or (now_us - q[-1]) * 1e-6 > 2.5 / rate:
            return 0.0
        return rate

    def clear(self) -> None:
        self._q.clear()


class Monitor:
    """Three channels and their integrity control, as a pure fold over samples."""

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.mcfg = cfg.monitor
        self.model = Model.from_config(cfg)
        self.counters: Counter[str] = Counter()
        self.k_vpl = normal_k(self.mcfg.integrity_risk)
        self.boot = 0
        self.logic = None
        self._reset()

    # ------------------------------------------------------------------ lifecycle

    def _reset(self) -> None:
        from .hypotheses import HypothesisLogic
        from .paper import PaperLogic

        if self.logic is not None:  # the boot before: what its logic did that the counters report
            self.counters["glitch_restarts"] += getattr(self.logic, "glitch_restarts", 0)
        self.builder = EpochBuilder(self.cfg)
        self.bank = ChannelBank(self.model)
        logic_cls = PaperLogic if self.mcfg.mode == "paper" else HypothesisLogic
        self.logic = logic_cls(self.cfg, self.bank)
        self.raw = {BARO_S: math.nan, GNSS_S: math.nan, RNG_S: math.nan, AUTOPILOT: math.nan}
        self.rates = {k: RateMeter() for k in (IMU_S, BARO_S, GNSS_S, RNG_S)}
        self._imu_times = self.rates[IMU_S]._q  # push's inline RateMeter.push
        self.input = None  # SourceTracker, created at the first epoch
        self._link_lost = False
        self._pending: list[AlarmEvent] = []
        self._last_t_us: Optional[int] = None
        self._rates_checked_us: Optional[int] = None
        self._baro_at_datum = False  # this boot's baro reference was taken at the datum

    def counts(self) -> dict:
        """What happened over the run, every boot: the counters, with the
        current logic's starts again on a baro glitch."""
        out = dict(self.counters)
        n = out.get("glitch_restarts", 0) + getattr(self.logic, "glitch_restarts", 0)
        if n:
            out["glitch_restarts"] = n
        return out

    # ------------------------------------------------------------------ fold

    def push(self, s) -> list[tuple[EpochReport, list[AlarmEvent]]]:
        """Consume one sample or event; return the epochs it completed."""
        if type(s) is SpecificForceUp:  # most samples (onboard logs: about 40 per epoch): the shortest way
            t_us = s.t_us
            q = self._imu_times  # RateMeter.push, inline
            q.append(t_us)
            limit = t_us - _RATE_WINDOW_US
            while q[0] <= limit:
                q.popleft()
            eps = self.builder._on_imu(t_us, s.f_up_mps2)  # EpochBuilder.push's IMU branch
            return self._epochs(eps) if eps else eps
        kind = type(s)
        if kind is AutopilotHeight:  # the next most (onboard logs: about two per epoch): no epoch from it
            self.raw[AUTOPILOT] = s.height_ref_m
            return []
        if kind is BaroHeight:  # one per epoch
            self.raw[BARO_S] = s.height_ref_m
            self.rates[BARO_S].push(s.t_us)
            eps = self.builder._on_baro(s)  # EpochBuilder.push's baro branch
            return self._epochs(eps) if eps else eps
        if kind is RangeHeight:  # the aux samples: EpochBuilder.push's branches, no epoch from them
            self.raw[RNG_S] = s.height_agl_m
            self.rates[RNG_S].push(s.t_us)
            self.builder._on_aux(s, "rng")
            return []
        if kind is GnssHeight:
            self.raw[GNSS_S] = s.height_ref_m
            self.rates[GNSS_S].push(s.t_us)
            self.builder._on_aux(s, "gnss")
            return []
        # (the sample types above are final: no subclass reaches the events below)
        if isinstance(s, Reboot):
            self.counters["reboots"] += 1
            self._on_reboot(s)
            return []
        elif isinstance(s, Rejected):
            if s.t_us is not None and s.sensor == RANGE_STREAM:
                self.logic.on_range_refused(s)
        elif isinstance(s, ReferenceSet):
            if s.kind == BARO_S:
                self._baro_at_datum = s.at_datum
        elif isinstance(s, LinkLost):
            self._link_lost = True
            self._input_event("unavailable", f"link lost ({s.silent_s:.1f} s silent)")
        elif isinstance(s, LinkRecovered):
            self._link_lost = False
            self._input_event("nominal", f"link recovered after {s.outage_s:.1f} s")
        return self._epochs(self.builder.push(s))

    def push_run(self, ts: list, fs: list, i: int, j: int, t_arr=None,
                 f_arr=None) -> tuple[int, list[tuple[EpochReport, list[AlarmEvent]]]]:
        """:meth:`push` of the IMU samples ``ts[i:j]``, ``fs[i:j]`` (an
        :class:`~mavnav.ingest.onboard.imurun.ImuRun`'s columns, times strictly
        increasing; ``t_arr``, ``f_arr`` its array columns, if any) up to the
        first that completes an epoch: ``(k, epochs)``, samples ``i .. k - 1``
        consumed and the epochs the last of them completed, as :meth:`push`
        of each in turn would return them."""
        k, eps = self.builder._on_imu_run(ts, fs, i, j, t_arr, f_arr)
        q = self._imu_times  # RateMeter.push of each, at once: the window ends at the last
        q += ts[i:k]
        limit = ts[k - 1] - _RATE_WINDOW_US
        while q[0] <= limit:
            q.popleft()
        return k, (self._epochs(eps) if eps else eps)

    def _epochs(self, eps) -> list[tuple[EpochReport, list[AlarmEvent]]]:
        """The builder's starts and epochs, in order: the reports of the epochs."""
        out = []
        for ep in eps:
            if isinstance(ep, EpochStart):
                at_datum = self._baro_at_datum and self.mcfg.mode != "paper"
                p0 = self.cfg.filter.p0
                self.bank.start(ep.t_us, ep.baro_m, p0.baro_bias_at_datum_m2 if at_datum else None,
                                p0.vel_at_datum_m2ps2 if at_datum else None)
                self.logic.start(ep.t_us, self.boot, self._baro_at_datum)
                if self.input is None:
                    self.input = SourceTracker(INPUT, ep.t_us, self.boot)
                self.counters["starts"] += 1
                continue
            out.append(self._epoch(ep))
        return out

    def _on_reboot(self, s: Reboot) -> None:
        # Close the previous boot's alarms honestly: everything restarts.
        self.boot = s.boot
        self._reset()

    def _input_event(self, state: str, reason: str) -> None:
        if self.input is None or self._last_t_us is None:
            return
        ev = self.input.set(state, self._last_t_us, reason)
        if ev is not None:
            self._pending.append(ev)

    # ------------------------------------------------------------------ epoch

    def _height_sensors(self, d) -> list:
        """The height sensors the monitor has this epoch: the baro unless it is
        out, the GNSS and the rangefinder while their channels are available."""
        out = [] if d.sources[BARO_INS_S].state in ("alarm", "unavailable") else ["baro"]
        return out + [n for n, c in (("GNSS", GNSS), ("rangefinder", RNG)) if d.available[c]]

    def _input_state(self, t_us: int, d) -> Optional[AlarmEvent]:
        if self.input is None:
            self.input = SourceTracker(INPUT, t_us, self.boot)
        if self._link_lost:
            return None
        if self._rates_checked_us is not None and t_us - self._rates_checked_us < 1_000_000:
            return None
        self._rates_checked_us = t_us
        m = self.mcfg
        need_aux = max(m.alarm_rejections, 1) / m.time_to_alarm_s
        need = {IMU_S: m.min_imu_rate_hz, BARO_S: m.min_baro_rate_hz, GNSS_S: need_aux, RNG_S: need_aux}
        slow = []
        since_start = (t_us - self.logic.t0_us) * 1e-6
        slow_imu_hz = None
        if since_start >= _RATE_WINDOW_US * 1e-6:
            for k, meter in self.rates.items():
                r = meter.rate_hz(t_us)
                if r <= 0.0:
                    continue  # absent inputs are the channels' business (unavailable)
                if r < m.rate_tolerance_frac * need[k]:
                    slow.append(f"{k} {r:.1f} Hz < {need[k]:.0f}")
                    if k == IMU_S:
                        slow_imu_hz = r
        self.logic.slow_imu_hz = slow_imu_hz  # the INS tests' witness is too sparse to judge the baro
        if slow:
            # slow inputs make monitoring unavailable at the required time-to-alarm; they never make a sensor faulty
            return self.input.set("unavailable", t_us, "monitoring degraded, too slow for the %.1f s time-to-alarm: %s"
                                  % (m.time_to_alarm_s, ", ".join(slow)))
        have = self._height_sensors(d)
        if self.mcfg.mode != "paper" and len(have) < m.min_height_sensors:
            return self.input.set("unavailable", t_us, "monitoring degraded: %s and the INS alone; a slow error "
                                  "in a single height sensor cannot be detected within the time-to-alarm"
                                  % (" and ".join(have) or "no height sensor"))
        return self.input.set("nominal", t_us, "rates support the time-to-alarm")

    def _epoch(self, ep: EpochInputs) -> tuple[EpochReport, list[AlarmEvent]]:
        t_us = ep.t_us
        self._last_t_us = t_us
        ep_used = self.logic.pre(ep)
        step = self.bank.step(ep_used)
        d = self.logic.post(ep, ep_used, step)
        events = self._pending + d.events
        self._pending = []
        ev = self._input_state(t_us, d)
        if ev is not None:
            events.append(ev)
        bank = self.bank
        xs = bank.x.tolist()
        phh = bank.P[:, 0, 0].tolist()
        ivar = step.innovation_var.tolist()
        inn = step.innovation.tolist()
        nis = step.nis.tolist()
        dof = step.dof.tolist()
        avail, used = d.available, d.used
        chans = []
        for c, name in enumerate(CHANNEL_NAMES):
            x = xs[c]
            sb, sa = ivar[c]
            ib, ia = inn[c]
            p = phh[c]
            chans.append(ChannelReport(
                name, x[0], math.sqrt(0.0 if 0.0 > p else p), x[1], x[2], x[3],  # max(p, 0.0), NaN kept
                bool(avail[c]), bool(used[c]), nis[c], dof[c],
                ib / math.sqrt(sb) if sb == sb else math.nan,
                ia / math.sqrt(sa) if sa == sa else math.nan,
            ))
        sources = d.sources  # the logic's own dict, built for this epoch: the input's status joins it
        input_status = sources[INPUT] = self.input.status()
        if d.vpl_m == d.vpl_m:
            vpl = d.vpl_m
        else:
            vpl = self.k_vpl * d.sigma_fused_m if d.sigma_fused_m == d.sigma_fused_m else math.inf
        # A source that is merely unavailable (no data) does not degrade the
        # overall state by itself: the protection level says whether what is
        # left still supports the alert limit.
        states = [st.state for st in sources.values()]
        alert_limit_m = self.mcfg.alert_limit_m
        if "alarm" in states:
            overall = "alarm"
        elif (not (vpl <= alert_limit_m) or d.height_fused_m != d.height_fused_m
              or input_status.state == "unavailable"):
            overall = "unavailable"
        elif "caution" in states:
            overall = "caution"
        else:
            overall = "nominal"
        raw = self.raw
        report = EpochReport(t_us, self.boot, d.height_fused_m, d.sigma_fused_m, tuple(chans), d.pairs, sources,
                             overall, vpl, alert_limit_m,  # type: ignore[arg-type]
                             raw[BARO_S], raw[GNSS_S], raw[RNG_S], raw[AUTOPILOT], self.mcfg.mode)
        return report, events

