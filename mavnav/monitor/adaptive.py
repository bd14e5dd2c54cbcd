"""``mode: adaptive`` (the default): the paper's channel comparison, made safe.

Each addition is switchable in ``monitor.features`` and tested to pay for
itself (``tests/test_monitor_*.py``):

* **covariance thresholds**: a pair of channels disagrees when
  ``|H_a - H_b| > k sqrt(P_a + P_b - 2 P_ab)``, with the cross-covariance the
  channels share through the baro and the INS (propagated by the bank) and
  ``k`` from ``false_alarm_prob``;
* **innovation gating**: each GNSS / rangefinder sample's normalised
  innovation is tested (chi-square, 1 dof, ``gate_prob``) *before* it enters
  its channel; a rejected sample never touches the state;
* **window test**: the sum of squared normalised innovations of each source
  over ``window_s`` against two-sided chi-square bounds (``window_prob``):
  above, a slow drift; below, a source quieter than its model (stuck);
* **2-of-3 isolation**: GNSS and rangefinder agreeing against baro+INS blame
  baro+INS (the paper would exclude the two healthy channels);
* **validated feedback**: the reference channel (baro+INS) is corrected only
  from channels that have been nominal for ``validate_s``, weakly
  (``feedback_inflation``) and every ``feedback_interval_s``, never while it
  is itself in alarm, so a slow ramp cannot drag the reference along while
  it is being detected;
* **readmission**: an excluded source comes back after ``readmit_s`` of
  consistency (its raw value against the others' fused height, or for
  baro+INS its channel against the others), with its channel re-initialised;
* **inverse-variance fusion** of the passing channels, with cross-covariances.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from typing import Optional

import numpy as np

from ..bank import BARO, GNSS, RNG, ChannelBank
from ..channel import EpochInputs
from ..config import Config
from .decision import Decision, diff_sigmas, pair_reports
from .fusion import fuse_heights
from .levels import chi2_gate, chi2_window, normal_k
from .rawcheck import RawAuxCheck
from .tracker import SourceTracker
from .window import InnovationWindow

AUX = ((GNSS, "gnss"), (RNG, "rangefinder"))
CHANNEL_LABEL = {GNSS: "GNSS", RNG: "rangefinder", BARO: "baro+INS"}
P12, P13, P23 = 0, 1, 2  # pair indices (gnss-rng, gnss-baro, rng-baro)


class AdaptiveLogic:
    def __init__(self, cfg: Config, bank: ChannelBank):
        self.m = m = cfg.monitor
        self.f = m.features
        self.bank = bank
        self.k_cmp = normal_k(m.false_alarm_prob)
        self.gate = chi2_gate(m.gate_prob)
        self.baro_gate = chi2_gate(m.baro_jump_prob)
        self.persist_us = int(m.persist_s * 1e6)
        self.readmit_us = int(m.readmit_s * 1e6)
        self.validate_us = int(m.validate_s * 1e6)
        self.feedback_us = int(m.feedback_interval_s * 1e6)
        self.stale_us = {GNSS: int(m.stale_gnss_s * 1e6), RNG: int(m.stale_rng_s * 1e6)}
        self.stale_baro_us = int(m.stale_baro_s * 1e6)
        self.t0_us = 0
        self.warmup_us = int(m.warmup_s * 1e6)

    # ------------------------------------------------------------------ state

    def start(self, t_us: int, boot: int) -> None:
        m = self.m
        self.t0_us = t_us
        self.boot = boot
        clear_us = int(m.clear_s * 1e6)
        self.trackers = {s: SourceTracker(s, t_us, boot, clear_us=clear_us) for s in ("gnss", "rangefinder", "baro_ins")}
        # a rejected sample weighs at most the gate in the window: one wild
        # sample is the gate's business, alarms from rejections need several
        self.windows = {"gnss": InnovationWindow(m.window_s, cap=self.gate),
                        "rangefinder": InnovationWindow(m.window_s, cap=self.gate),
                        "baro_ins": InnovationWindow(m.window_s, cap=self.gate)}
        self.excluded: set[str] = set()
        self.last_accept_us: dict[int, Optional[int]] = {GNSS: None, RNG: None}
        self.last_seen_us: dict[int, Optional[int]] = {GNSS: None, RNG: None}
        self.last_baro_us = t_us
        self.exceed_since: list[Optional[int]] = [None, None, None]
        self.consistent_since: dict[str, Optional[int]] = {"gnss": None, "rangefinder": None, "baro_ins": None}
        self.last_nu2 = {GNSS: math.nan, RNG: math.nan}
        self.last_baro_nu2 = math.nan
        self.level_since: Optional[int] = None
        self.level_txt = ""
        self.last_baro_m: Optional[float] = None
        self.bank.baro_on[:] = True
        self.pending_raw: dict[int, Optional[tuple]] = {GNSS: None, RNG: None}
        self.sensor_var_floor = [0.0, 0.0, 0.0]
        self.range_refused: deque = deque()
        self.range_valid: list[int] = []
        self.warm_until = {"gnss": t_us + self.warmup_us, "rangefinder": t_us + self.warmup_us,
                           "baro_ins": t_us + self.warmup_us}
        self.last_feedback_us = t_us
        self.raw_check = RawAuxCheck(window_s=1.0, k=self.k_cmp)

    # ------------------------------------------------------------------ refused readings

    ERRATIC_KINDS = ("out_of_range", "stuck", "impossible", "nan")

    def on_range_refused(self, t_us: int, kind: str) -> None:
        """A rangefinder reading refused at ingestion (``invalid_quality`` is the
        sensor's own honest 'no reading' and does not count)."""
        if kind in self.ERRATIC_KINDS and hasattr(self, "range_refused"):
            self.range_refused.append((t_us, kind))

    def _erratic_range(self, t: int) -> Optional[str]:
        """Valid readings mixed with refused ones: an erratic sensor (alarm),
        not a sensor that is merely out of its range (unavailable)."""
        q = self.range_refused
        limit = t - self.windows["rangefinder"].length_us
        while q and q[0][0] <= limit:
            q.popleft()
        self.range_valid = [v for v in self.range_valid if v > limit]
        n_bad, n_ok = len(q), len(self.range_valid)
        if n_bad >= 3 and n_ok >= 5 and n_bad >= 0.1 * (n_bad + n_ok):
            kinds = sorted({k for _, k in q})
            return (f"erratic: {n_bad} of {n_bad + n_ok} readings in {self.m.window_s:g} s refused "
                    f"({', '.join(kinds)})")
        return None

    # ------------------------------------------------------------------ before the step

    def pre(self, ep: EpochInputs) -> EpochInputs:
        """Gate GNSS / rangefinder samples and keep excluded sources out."""
        bank = self.bank
        t = ep.t_us
        changes = {}
        for c, name in AUX:
            aux = ep.gnss if c == GNSS else ep.rng
            self.pending_raw[c] = None
            if aux is None:
                continue
            self.last_seen_us[c] = t
            if c == RNG:
                self.range_valid.append(t)
            self.pending_raw[c] = (aux.height_m - aux.age_s * bank.x[c, 1], aux.sigma_m)
            # the sensor's own 1-sigma includes slow errors the white-noise
            # model averages away: no channel knows H better than its sensor
            self.sensor_var_floor[c] = aux.sigma_m * aux.sigma_m
            field_name = "gnss" if c == GNSS else "rng"
            if name in self.excluded:
                changes[field_name] = None  # the channel coasts; readmission decides later
                continue
            r, S = bank.predicted_aux(c, ep, aux)
            nu2 = r * r / S if S > 0 else math.inf
            self.last_nu2[c] = nu2
            reject = self.f.innovation_gating and nu2 > self.gate
            if (self.f.window_test or self.f.innovation_gating) and t >= self.warm_until[name]:
                self.windows[name].push(t, nu2, reject)
            if reject:
                changes[field_name] = None
            else:
                self.last_accept_us[c] = t
        if ep.baro_m is not None:
            self.last_baro_us = t
            self.last_baro_m = ep.baro_m
            if "baro_ins" not in self.excluded:
                reject = self._judge_baro(ep)
                if reject:
                    changes["baro_restart"] = True  # no baro row anywhere; differencing restarts
        return dataclasses.replace(ep, **changes) if changes else ep

    def _anchors(self) -> list[int]:
        """Channels held by an independent height sensor that is not in alarm."""
        out = []
        for c, name in AUX:
            if name in self.excluded or self.last_accept_us[c] is None or self.trackers[name].state == "alarm":
                continue
            if self.bank.baro_on[c]:
                out.append(c)
        return out

    def _baro_level(self, t: int) -> tuple[bool, bool]:
        """Level test of the baro against the anchored channels' ``H + dH``.

        The differenced baro row is nearly blind to a slowly growing offset
        (its sensitivity to the level is ``1 - phi_u``) and the feedback would
        fold such an offset into the reference's bias; the level residual
        ``baro - (H + dH)`` of a channel held by GNSS or the rangefinder sees
        it directly. With two anchors both must agree (a step of one anchor's
        own sensor is not the baro's fault). Returns (exceeded now,
        confirmed for persist_s).
        """
        anchors = self._anchors()
        if not anchors or self.last_baro_m is None or "baro_ins" in self.excluded:
            self.level_since = None
            return False, False
        bank = self.bank
        best = min(anchors, key=lambda c: bank.P[c, 0, 0])
        texts = []
        exceeded = {}
        for c in anchors:
            x, P = bank.x[c], bank.P[c]
            r = self.last_baro_m - (x[0] + x[2])
            var = P[0, 0] + P[2, 2] + 2.0 * P[0, 2] + bank.model.sigma_bb_m ** 2
            thr = self.k_cmp * math.sqrt(var)
            exceeded[c] = abs(r) > thr
            texts.append(f"{r:+.2f} m from the {CHANNEL_LABEL[c]} channel (threshold {thr:.2f} m)")
        # suspicion from the best anchor (a caution, and no aux sensor is
        # blamed meanwhile). An alarm when every anchor agrees, or when the best
        # one does and the raw GNSS and rangefinder agree with each other (then
        # the anchor's own sensor is not the culprit: 2-of-3 without the baro)
        suspect = exceeded[best]
        raw = self.raw_check.verdict()
        raw_vouches = raw is not None and raw[0] and len(anchors) == 2
        if not (all(exceeded.values()) or (suspect and raw_vouches)):
            self.level_since = None
            if suspect:
                self.level_txt = "baro " + "; ".join(texts)
            return suspect, False
        if self.level_since is None:
            self.level_since = t
        self.level_txt = "baro " + "; ".join(texts)
        return True, t - self.level_since >= self.persist_us

    def _warming(self, t: int) -> bool:
        return t - self.t0_us < self.warmup_us

    def _anchor(self) -> int:
        """The channel whose view of the baro is most trustworthy: the one with
        an independent height sensor and the smallest height variance."""
        best, best_var = BARO, math.inf
        for c, name in AUX:
            last = self.last_accept_us[c]
            if name in self.excluded or last is None or self.trackers[name].state == "alarm":
                continue
            if self.bank.P[c, 0, 0] < best_var:
                best, best_var = c, self.bank.P[c, 0, 0]
        return best

    def _judge_baro(self, ep: EpochInputs) -> bool:
        """Gate the baro sample on its innovation in the anchor channel."""
        c = self._anchor()
        r, S = self.bank.predicted_baro(c, ep)
        if not (S == S and S > 0):
            return False
        nu2 = r * r / S
        reject = self.f.innovation_gating and nu2 > self.baro_gate
        if (self.f.window_test or self.f.innovation_gating) and not self._warming(ep.t_us):
            self.windows["baro_ins"].push(ep.t_us, nu2, reject)
        self.last_baro_nu2 = nu2
        return reject

    # ------------------------------------------------------------------ after the step

    def _available(self, t: int) -> tuple[bool, bool, bool]:
        bank = self.bank
        max_var = self.m.max_channel_sigma_m ** 2
        out = []
        for c, name in AUX:
            last = self.last_accept_us[c]
            ok = (name not in self.excluded and last is not None and t - last <= self.stale_us[c]
                  and bank.P[c, 0, 0] <= max_var)
            out.append(ok)
        out.append(t - self.last_baro_us <= self.stale_baro_us and bank.P[BARO, 0, 0] <= max_var)
        return tuple(out)  # type: ignore[return-value]

    def _thresholds(self) -> np.ndarray:
        if self.f.covariance_thresholds:
            return self.k_cmp * diff_sigmas(self.bank, self.sensor_var_floor)
        m = self.m
        return np.array([m.delta_gnss_m, m.delta_gnss_m, m.delta_ra_m])

    def _window_verdict(self, name: str) -> tuple[str, str, float, float]:
        """("high" | "low" | "ok", reason, low bound, high bound) of a source's window."""
        w = self.windows[name]
        if not self.f.window_test or w.n < self.m.window_min_samples:
            return "ok", "", math.nan, math.nan
        lo, hi = chi2_window(w.n, self.m.window_prob)
        if w.total > hi:
            return "high", f"innovations too large over {self.m.window_s:g} s (sum {w.total:.0f} > {hi:.0f})", lo, hi
        if w.total < lo and self.m.window_low_test:
            return "low", f"innovations too small over {self.m.window_s:g} s (sum {w.total:.1f} < {lo:.1f})", lo, hi
        return "ok", "", lo, hi

    def post(self, ep: EpochInputs, ep_used: EpochInputs, step) -> Decision:
        bank = self.bank
        m = self.m
        t = ep.t_us
        for w in self.windows.values():
            w.expire(t)
        self.raw_check.push(t, self.pending_raw[GNSS], self.pending_raw[RNG])
        avail = self._available(t)
        thr = self._thresholds()
        pairs = pair_reports(bank, avail, thr)
        # persistence of each pair's disagreement
        confirmed = []
        for p, pr in enumerate(pairs):
            if pr.exceeded:
                if self.exceed_since[p] is None:
                    self.exceed_since[p] = t
                confirmed.append(t - self.exceed_since[p] >= self.persist_us)
            else:
                self.exceed_since[p] = None
                confirmed.append(False)
        if self._warming(t):
            blame, caution = {}, {}
            self.exceed_since = [None, None, None]
        else:
            blame, caution = self._isolate(pairs, confirmed)
        events = []
        verdicts = {}
        # --- baro+INS first: a baro fault contaminates both aux channels, so
        # while the baro is suspect, their disagreements blame nobody
        tr = self.trackers["baro_ins"]
        wv, wreason, lo, hi = self._window_verdict("baro_ins")
        verdicts["baro_ins"] = (lo, hi)
        brej = self.windows["baro_ins"].rejected
        level_now, level_confirmed = (self._baro_level(t) if self.f.isolation_2of3 and not self._warming(t)
                                      else (False, False))
        baro_suspect = level_now
        if t - self.last_baro_us > self.stale_baro_us:
            ev = tr.set("unavailable", t, "no recent baro")
        elif "baro_ins" in self.excluded:
            ev = self._maybe_readmit_baro(t, pairs)
            baro_suspect = True
        elif brej >= 1 and self.f.innovation_gating:
            ev = self._exclude("baro_ins", t, f"baro jump rejected ({math.sqrt(self.last_baro_nu2):.1f} sigma "
                                              f"against the {CHANNEL_LABEL[self._anchor()]} channel)")
            baro_suspect = True
        elif level_confirmed:
            ev = self._exclude("baro_ins", t, self.level_txt)
            baro_suspect = True
        elif "baro_ins" in blame:
            ev = self._exclude("baro_ins", t, blame["baro_ins"])
            baro_suspect = True
        elif "baro_ins" in caution or wv != "ok" or level_now:
            # the baro's innovation window alone is a caution (and vetoes no
            # other verdict): it is the test most sensitive to a mismatched
            # noise model; ramps are the level test's
            ev = tr.set("caution", t, caution.get("baro_ins") or self.level_txt or
                        (wreason + f" (baro in the {CHANNEL_LABEL[self._anchor()]} channel)"))
        else:
            ev = tr.set("nominal", t, "consistent")
        if ev is not None:
            events.append(ev)
        # --- aux sources
        for c, name in AUX:
            tr = self.trackers[name]
            wv, wreason, lo, hi = self._window_verdict(name)
            verdicts[name] = (lo, hi)
            rej = self.windows[name].rejected
            pair_blame = None if baro_suspect else blame.get(name)
            erratic = self._erratic_range(t) if c == RNG and not self._warming(t) else None
            if name in self.excluded:
                if erratic is not None:
                    self.consistent_since[name] = None  # still refusing readings: not consistent
                    ev = None
                else:
                    ev = self._maybe_readmit_aux(c, name, t, avail)
            elif self.last_seen_us[c] is None or t - self.last_seen_us[c] > self.stale_us[c]:
                ev = tr.set("unavailable", t, "no recent data")
            elif rej >= m.alarm_rejections and self.f.innovation_gating:
                ev = self._exclude(name, t, f"{rej} samples rejected in {m.window_s:g} s "
                                            f"(last {math.sqrt(self.last_nu2[c]):.1f} sigma)")
            elif erratic is not None:
                ev = self._exclude(name, t, erratic)
            elif pair_blame is not None:
                ev = self._exclude(name, t, pair_blame)
            elif wv == "high" and not baro_suspect:
                ev = self._exclude(name, t, wreason)
            elif rej >= m.caution_rejections or name in caution or wv != "ok":
                reason = caution.get(name) or wreason or f"{rej} samples rejected in {m.window_s:g} s"
                ev = tr.set("caution", t, reason)
            else:
                ev = tr.set("nominal", t, "consistent")
            if ev is not None:
                events.append(ev)
        # --- fusion of the passing channels
        used = tuple(avail[c] and self.trackers[n].state in ("nominal", "caution")
                     for c, n in ((GNSS, "gnss"), (RNG, "rangefinder"), (BARO, "baro_ins")))
        idx = [c for c in range(3) if used[c]]
        h, sigma = math.nan, math.nan
        if idx:
            h, sigma, _ = fuse_heights([bank.x[c, 0] for c in idx], bank.height_cov(idx), self.f.inverse_variance)
        if self.f.validated_feedback:
            self._feedback(t, avail)
        else:
            self._paper_feedback(idx)
        statuses = {}
        for name, trk in self.trackers.items():
            lo, hi = verdicts[name]
            w = self.windows[name]
            statuses[name] = trk.status(window_stat=w.total if w.n else math.nan, window_low=lo,
                                        window_high=hi, rejected=w.rejected)
        return Decision(available=avail, used=used, pairs=pairs, sources=statuses,
                        height_fused_m=h, sigma_fused_m=sigma, events=events)

    # ------------------------------------------------------------------ isolation

    def _isolate(self, pairs, confirmed) -> tuple[dict, dict]:
        """Which source to blame (alarm) and which to watch (caution)."""
        blame: dict[str, str] = {}
        caution: dict[str, str] = {}
        v = [pr.valid for pr in pairs]
        e = [pr.exceeded for pr in pairs]
        ce = confirmed

        def why(p):
            pr = pairs[p]
            return f"{pr.name} {pr.diff_m:+.2f} m, threshold {pr.threshold_m:.2f} m"

        if all(v) and self.f.isolation_2of3:
            raw = self.raw_check.verdict()
            raw_agree = raw is None or raw[0]
            raw_txt = "" if raw is None else f"; raw GNSS-rangefinder {raw[1]:+.2f} m"
            if ce[P13] and ce[P23] and (raw_agree or not e[P12]):
                blame["baro_ins"] = (f"GNSS and rangefinder agree against baro+INS ({why(P13)}; {why(P23)}"
                                     f"{raw_txt})")
            elif ce[P12] and not raw_agree and ce[P13] and not e[P23]:
                blame["gnss"] = f"disagrees with rangefinder and baro+INS ({why(P12)}; {why(P13)}{raw_txt})"
            elif ce[P12] and not raw_agree and ce[P23] and not e[P13]:
                blame["rangefinder"] = f"disagrees with GNSS and baro+INS ({why(P12)}; {why(P23)}{raw_txt})"
            elif ce[P12] and ce[P13] and ce[P23]:
                blame["baro_ins"] = "no two channels agree"
                caution["gnss"] = caution["rangefinder"] = "no two channels agree"
            else:
                if e[P12] and raw_agree:
                    # the aux channels differ only through the baro they share
                    caution["baro_ins"] = why(P12) + raw_txt + ": the raw sensors agree"
                for p, names in ((P12, ("gnss", "rangefinder")), (P13, ("gnss", "baro_ins")),
                                 (P23, ("rangefinder", "baro_ins"))):
                    if e[p] and not (p == P12 and raw_agree):
                        for n in names:
                            caution.setdefault(n, why(p))
            return blame, caution
        # fewer than three channels (or 2-of-3 switched off): the paper's rule,
        # the aux channel is blamed against baro+INS
        if v[P13] and ce[P13]:
            blame["gnss"] = f"disagrees with baro+INS ({why(P13)})"
        elif v[P13] and e[P13]:
            caution["gnss"] = why(P13)
        if v[P23] and ce[P23]:
            blame["rangefinder"] = f"disagrees with baro+INS ({why(P23)})"
        elif v[P23] and e[P23]:
            caution["rangefinder"] = why(P23)
        if v[P12] and e[P12] and not (v[P13] or v[P23]):
            caution["gnss"] = caution["rangefinder"] = why(P12) + "; cannot isolate"
        return blame, caution

    def _exclude(self, name: str, t: int, reason: str):
        self.excluded.add(name)
        self.consistent_since[name] = None
        if name == "baro_ins":
            # a faulty baro is taken out of every channel, not only the fusion
            self.bank.baro_on[GNSS] = self.bank.baro_on[RNG] = False
        else:
            self.windows[name].clear()
        return self.trackers[name].set("alarm", t, reason)

    # ------------------------------------------------------------------ readmission

    def _others_fused(self, exclude: int) -> Optional[tuple[float, float]]:
        bank = self.bank
        idx = [c for c, n in ((GNSS, "gnss"), (RNG, "rangefinder"), (BARO, "baro_ins"))
               if c != exclude and n not in self.excluded and bank.P[c, 0, 0] <= self.m.max_channel_sigma_m ** 2]
        if not idx:
            return None
        h, s, _ = fuse_heights([bank.x[c, 0] for c in idx], bank.height_cov(idx), True)
        return h, s

    def _maybe_readmit_aux(self, c: int, name: str, t: int, avail):
        tr = self.trackers[name]
        raw = self.pending_raw[c]
        if raw is None:
            if self.last_seen_us[c] is not None and t - self.last_seen_us[c] > self.stale_us[c]:
                self.consistent_since[name] = None
            return None
        ref = self._others_fused(c)
        if ref is None:
            return None
        z, sigma = raw
        h, s = ref
        ok = abs(z - h) <= self.k_cmp * math.hypot(sigma, s)
        if not ok:
            self.consistent_since[name] = None
            return None
        if self.consistent_since[name] is None:
            self.consistent_since[name] = t
        if not self.f.readmission or t - self.consistent_since[name] < self.readmit_us:
            return None
        self.excluded.discard(name)
        src = min((j for j, n in ((GNSS, "gnss"), (RNG, "rangefinder"), (BARO, "baro_ins"))
                   if j != c and n not in self.excluded), key=lambda j: self.bank.P[j, 0, 0], default=BARO)
        self.bank.reinit_from(c, src, extra_height_var=sigma * sigma)
        self.warm_until[name] = t + self.warmup_us
        self.last_accept_us[c] = t
        self.windows[name].clear()
        return tr.set("nominal", t, f"readmitted after {self.m.readmit_s:g} s consistent; channel re-initialised")

    def _maybe_readmit_baro(self, t: int, pairs):
        tr = self.trackers["baro_ins"]
        checks = [pairs[p] for p in (P13, P23) if pairs[p].valid]
        if not checks or any(pr.exceeded for pr in checks):
            self.consistent_since["baro_ins"] = None
            return None
        if self.consistent_since["baro_ins"] is None:
            self.consistent_since["baro_ins"] = t
        if not self.f.readmission or t - self.consistent_since["baro_ins"] < self.readmit_us:
            return None
        self.excluded.discard("baro_ins")
        self.windows["baro_ins"].clear()
        self.bank.baro_on[:] = True  # differencing restarts in the aux channels
        return tr.set("nominal", t, f"readmitted after {self.m.readmit_s:g} s consistent")

    # ------------------------------------------------------------------ feedback

    def _validated(self, t: int, avail) -> list[int]:
        out = []
        for c, name in AUX:
            tr = self.trackers[name]
            if avail[c] and tr.state == "nominal" and t - tr.since_us >= self.validate_us:
                out.append(c)
        return out

    def _feedback(self, t: int, avail) -> None:
        """Correct the reference channel from validated channels.

        Exact in covariance (the bank keeps the cross-covariances through it);
        weak by design: the gain uses the sources' variance times
        ``feedback_inflation``, so once the reference is calibrated it follows
        the others only slowly, and a slow ramp shows as a growing difference
        instead of being absorbed.
        """
        if t - self.last_feedback_us < self.feedback_us:
            return
        self.last_feedback_us = t
        if "baro_ins" in self.excluded or self.trackers["baro_ins"].state != "nominal":
            return  # never fold a suspect baro into the reference's bias
        src = self._validated(t, avail)
        if not src:
            return
        bank = self.bank
        _, _, w = fuse_heights([bank.x[c, 0] for c in src], bank.height_cov(src), True)
        bank.feedback(BARO, list(src), np.asarray(w), inflation=self.m.feedback_inflation)

    def _paper_feedback(self, idx) -> None:
        """Without validated feedback: the paper's, every epoch, from the output."""
        if not idx:
            return
        self.bank.x[BARO] = self.bank.x[idx].mean(axis=0)
