"""``mode: paper``: the integrity control of the paper (Fig. 4), exactly.

1. ``d1 = |H_ch1 - H_ch3|``; if ``d1 > Delta_gnss`` channel 1 is excluded.
2. ``d2 = |H_ch2 - H_ch3|``; if ``d2 > Delta_ra`` channel 2 is excluded.
3. The output is the arithmetic mean of the passing state vectors (channel 3
   always passes).
4. The output is fed back into channel 3 (its state vector is replaced by the
   output).

What a product must add and the paper leaves open, kept minimal here: a
channel whose sensor has sent nothing for the stale time takes no part (the
paper assumes every sensor always reports), and an exclusion is an ``alarm``
of that source for as long as it lasts. Channel 3 is never blamed: that is
the paper's logic, wrong when the barometer or the INS fails.
"""

from __future__ import annotations

import numpy as np

from .. import sensors
from ..bank import BARO, GNSS, RNG, ChannelBank
from ..channel import EpochInputs
from ..config import Config
from .decision import Decision, pair_reports
from .tracker import SourceTracker


class PaperLogic:
    def __init__(self, cfg: Config, bank: ChannelBank):
        self.m = cfg.monitor
        self.bank = bank
        bank.track_cross = True  # only for an honest sigma of the output
        self.t0_us = 0
        self.trackers: dict[str, SourceTracker] = {}
        self.last_aux_us = {GNSS: None, RNG: None}
        self.last_baro_us = None

    def start(self, t_us: int, boot: int, at_datum: bool = True) -> None:
        self.t0_us = t_us
        self.trackers = {s: SourceTracker(s, t_us, boot) for s in sensors.SENSOR_SOURCES}
        self.last_baro_us = t_us

    def pre(self, ep: EpochInputs) -> EpochInputs:
        return ep

    def on_range_refused(self, s) -> None:
        pass  # the paper has no notion of refused readings

    def _fresh(self, c: int, t_us: int) -> bool:
        last = self.last_aux_us[c]
        stale = self.m.stale_gnss_s if c == GNSS else self.m.stale_rng_s
        return last is not None and (t_us - last) * 1e-6 <= stale

    def post(self, ep: EpochInputs, ep_used: EpochInputs, step) -> Decision:
        t = ep.t_us
        if ep.gnss is not None:
            self.last_aux_us[GNSS] = t
        if ep.rng is not None:
            self.last_aux_us[RNG] = t
        bank = self.bank
        avail = (self._fresh(GNSS, t), self._fresh(RNG, t), True)
        d1 = abs(bank.x[GNSS, 0] - bank.x[BARO, 0])
        d2 = abs(bank.x[RNG, 0] - bank.x[BARO, 0])
        pass1 = avail[GNSS] and d1 <= self.m.delta_gnss_m
        pass2 = avail[RNG] and d2 <= self.m.delta_ra_m
        used = (pass1, pass2, True)
        pairs = pair_reports(bank, avail, (self.m.delta_gnss_m, self.m.delta_gnss_m, self.m.delta_ra_m))
        events = []
        for c, name, ok, d, delta in ((GNSS, sensors.GNSS, pass1, d1, self.m.delta_gnss_m),
                                      (RNG, sensors.RANGEFINDER, pass2, d2, self.m.delta_ra_m)):
            tr = self.trackers[name]
            if not avail[c]:
                ev = tr.set("unavailable", t, "no recent data")
            elif not ok:
                ev = tr.set("alarm", t, f"|H_{name} - H_baro| = {d:.2f} m > {delta:g} m: excluded")
            else:
                ev = tr.set("nominal", t, "within threshold")
            if ev is not None:
                events.append(ev)
        # arithmetic mean of the passing state vectors, fed back into channel 3
        idx = [c for c in (GNSS, RNG, BARO) if used[c]]
        x_mean = bank.x[idx].mean(axis=0)
        w = np.full(len(idx), 1.0 / len(idx))
        h, var = bank.fused_from(idx, w)
        bank.x[BARO] = x_mean
        statuses = {k: tr.status() for k, tr in self.trackers.items()}
        return Decision(available=avail, used=used, pairs=pairs, sources=statuses,
                        height_fused_m=float(x_mean[0]), sigma_fused_m=float(np.sqrt(max(var, 0.0))),
                        events=events)
