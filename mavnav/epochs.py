"""Turn time-stamped samples into filter epochs.

An *epoch* is the end of one filter step. Epochs fall on barometer samples
(the measurement every channel shares), so the baro differencing of
MODEL.md section 4 always pairs consecutive baro samples. Between two epochs
the vertical specific force is integrated with a zero-order hold (each IMU
sample holds until the next one), giving the control increments ``dp_m`` and
``dv_mps`` of ``f_up - g``; with one IMU sample per epoch these are exactly the
paper's ``Psi W``.

Every stream is judged against its own cadence (the median of its recent
intervals), so the same rules hold at 400 Hz onboard and at 2 Hz telemetry:

* **IMU.** A sample holds for at most ``max(imu_hold_max_s, imu_hold_intervals
  x its interval)``; beyond that the acceleration is unknown and the
  kinematic model takes over (zero mean, variance from
  ``kinematic_accel_sigma_mps2``). What a held snapshot misses of the
  acceleration between samples is in ``dv_var_m2ps2``: the scatter of
  consecutive samples (half the mean squared difference, averaged over
  ``imu_scatter_window_s``) times the held duration times the hold length.
  It vanishes at high rates and dominates at telemetry rates; the filters add
  it to their process noise. Samples that arrive behind the epoch already
  made (a lagging IMU) only take over the hold: no segment has a negative
  duration.
* **GNSS and rangefinder.** Every sample not after an epoch is used at that
  epoch: all pending samples of a stream are averaged into one measurement
  (mean height, mean age, white variance divided by their number), so a
  20 Hz rangefinder under a 10 Hz baro loses nothing. A sample is late, and
  dropped, only when older than ``max(max_meas_latency_s,
  meas_latency_intervals x (baro interval + its own interval))`` (at most
  ``max_meas_age_s``) at its epoch.
* **Baro gaps.** When no baro sample comes for ``max(max_epoch_gap_s,
  epoch_gap_intervals x the baro interval)`` of IMU time (``max_meas_age_s``
  until the baro has shown its cadence), an epoch is forced
  at the IMU time without a baro row and the differencing restarts at the next
  baro sample. A baro sample that waits for IMU data that long is processed
  at once (the IMU then counts as held or unknown). A baro sample repeating
  the previous pressure exactly within ``baro_repeat_max_s`` is the same
  measurement sent again and makes no epoch (``baro_repeated``).

Pure: no clock, no I/O. ``push(sample)`` returns the epochs it completed;
``counters`` say what happened to every sample (``<kind>_used``,
``_late``, ``_before_start``, ...).
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right, insort
from collections import Counter, deque
from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from .channel import AuxMeasurement, EpochInputs, Model, accel_noise_q
from .config import Config
from .jit import njit
from .samples import BaroHeight, GnssHeight, RangeHeight, Reboot, SpecificForceUp


# The baro white-noise estimate squares a median of |second differences|:
# its relative standard error over n Gaussian samples is 2.33 / sqrt(n)
# (2 x the median's 1 / (2 f(m) sqrt(n)) / m for a half-normal, m = 0.6745;
# measured 0.30-0.35 at n = 61 on the simulator's Gauss-Markov baro), as for
# a chi-square variance estimate with nu = 2 n / 2.33^2 degrees of freedom.
# Consecutive second differences share two samples (lag-1 correlation -1/2
# for u, -2/3 for white noise), which halves the independent ones: the test
# uses nu = n / 2.33^2. (With 2 n, 12 of 40 simulated 20 s runs of u alone
# passed white noise on at some epoch, up to 0.45 m; with n, none.)
_MEDIAN_VAR_REL_SE = 2.33
# A measured variance below the modelled one's upper 3-sigma quantile
# (one-sided, level 0.00135) is the estimate's own scatter, not white noise.
BARO_WHITE_Z = 3.0


def chi2_ratio_quantile(nu: float, z: float) -> float:
    """Upper quantile of chi^2_nu / nu at the normal quantile ``z``
    (Wilson-Hilferty: within 1 % for nu >= 2)."""
    a = 2.0 / (9.0 * nu)
    return (1.0 - a + z * math.sqrt(a)) ** 3


@dataclass(frozen=True, slots=True)
class EpochStart:
    """The first epoch of a run (or after a reboot): channels initialise here."""

    t_us: int
    baro_m: float


Epoch = Union[EpochStart, EpochInputs]

_RAW_MAX = 256  # IMU samples that wait for an epoch before they are taken anyway (bounded memory)


class Cadence:
    """The typical interval of one stream: the median of its last intervals."""

    __slots__ = ("_last_t", "_dts", "interval_us")

    def __init__(self, n: int = 9):
        self._last_t: Optional[int] = None
        self._dts: deque[int] = deque(maxlen=n)
        self.interval_us: Optional[int] = None

    def push(self, t_us: int) -> None:
        last = self._last_t
        if last is not None and t_us > last:
            dts = self._dts
            dt = t_us - last
            if len(dts) == dts.maxlen and dts[0] == dt:
                dts.append(dt)  # the interval that leaves is the one that comes: same median
            else:
                dts.append(dt)
                self.interval_us = sorted(dts)[len(dts) // 2]
        self._last_t = t_us


# The compiled IMU pass's integer state (``_ki``): the scatter's sample count,
# then the IMU cadence (Cadence with n = 9): its last time, its interval, and
# the ring of its last intervals (count, index of the oldest, 9 slots).
_KI_N, _KI_HAS_LAST, _KI_LAST, _KI_HAS_IV, _KI_IV, _KI_CNT, _KI_HEAD, _KI_RING = range(8)
_CADENCE_N = 9


@njit(cache=True)
def _q2_kernel(tau, printed, sigma_a, alpha_a):  # pragma: no cover - compiled
    """``accel_noise_q(tau) ** 2`` (the same operations)."""
    if printed:
        q = sigma_a * math.sqrt(2.0 * tau / alpha_a)
    else:
        q = sigma_a * math.sqrt(2.0 / (alpha_a * tau))
    return q ** 2


@njit(cache=True)
def imu_kernel(raw_t, raw_f, ht, hf, hn, ks, ki, started, integrate, t0, t_end, g, hold_max_s, hold_intervals,
               kin_var, kin_tau, window_s, printed, sigma_a, alpha_a):  # pragma: no cover - compiled
    """:meth:`EpochBuilder._take_imu_reference` then, with ``integrate``,
    :meth:`EpochBuilder._integrate_reference` from ``t0`` to ``t_end``, over
    arrays: the held samples ``ht, hf[:hn]`` (the reference's deque; room
    for the new ones behind them), the new samples ``raw_t, raw_f``, the
    scatter variance ``ks[0]`` and the integer state ``ki`` (see ``_KI_*``).
    The same operations in the same order as the reference: the same floats.
    Returns ``(hn, unknown_us, unknown, dp, dv, dv_var)``; ``hn = -1`` when
    there is no sample to integrate from (the reference's IndexError)."""
    var = ks[0]
    n = ki[_KI_N]
    has_iv = ki[_KI_HAS_IV] != 0
    iv_us = ki[_KI_IV]
    has_prev = hn > 0
    prev_t = ht[hn - 1] if has_prev else 0
    prev_f = hf[hn - 1] if has_prev else 0.0
    tmp = np.empty(_CADENCE_N, np.int64)
    for k in range(raw_t.shape[0]):
        t_us = raw_t[k]
        f_up = raw_f[k]
        if has_prev:
            tau = (t_us - prev_t) * 1e-6
            iv = iv_us * 1e-6 if has_iv else 0.0
            if iv == 0.0:
                iv = tau
            qt = _q2_kernel(tau, printed, sigma_a, alpha_a)
            qi = _q2_kernel(iv, printed, sigma_a, alpha_a)
            d2 = 0.5 * (f_up - prev_f) ** 2 - 0.5 * (qt + qi)
            n += 1
            if var != var:
                var = d2
            else:
                a = (t_us - prev_t) * 1e-6 / window_s
                b = 1.0 / n
                if b > a:
                    a = b
                if not a < 1.0:
                    a = 1.0
                var += a * (d2 - var)
        if ki[_KI_HAS_LAST] != 0 and t_us > ki[_KI_LAST]:
            dt = t_us - ki[_KI_LAST]
            cnt = ki[_KI_CNT]
            head = ki[_KI_HEAD]
            if cnt == _CADENCE_N and ki[_KI_RING + head] == dt:
                ki[_KI_RING + head] = dt  # the interval that leaves is the one that comes: same median
                head = (head + 1) % _CADENCE_N
            else:
                if cnt == _CADENCE_N:
                    ki[_KI_RING + head] = dt
                    head = (head + 1) % _CADENCE_N
                else:
                    ki[_KI_RING + (head + cnt) % _CADENCE_N] = dt
                    cnt += 1
                for j in range(cnt):  # the ring in order (insertion: at most 9, no allocation), its median
                    v = ki[_KI_RING + (head + j) % _CADENCE_N]
                    p = j
                    while p > 0 and tmp[p - 1] > v:
                        tmp[p] = tmp[p - 1]
                        p -= 1
                    tmp[p] = v
                iv_us = tmp[cnt // 2]
                has_iv = True
            ki[_KI_CNT] = cnt
            ki[_KI_HEAD] = head
        ki[_KI_HAS_LAST] = 1
        ki[_KI_LAST] = t_us
        ht[hn] = t_us
        hf[hn] = f_up
        hn += 1
        prev_t = t_us
        prev_f = f_up
        has_prev = True
    ks[0] = var
    ki[_KI_N] = n
    ki[_KI_HAS_IV] = 1 if has_iv else 0
    ki[_KI_IV] = iv_us
    if not started and hn > 1:  # keep only the latest until the first baro
        ht[0] = ht[hn - 1]
        hf[0] = hf[hn - 1]
        hn = 1
    if not integrate:
        return hn, 0, False, 0.0, 0.0, 0.0
    # the zero-order-hold integral, as _integrate_reference
    iv_s = iv_us * 1e-6 if has_iv else 0.0
    hs = hold_intervals * iv_s
    hold_us = int((hs if hs > hold_max_s else hold_max_s) * 1e6)
    scatter = 0.0 if var != var else (0.0 if 0.0 > var else var)
    t = t0
    h = 0
    while hn - h > 1 and ht[h + 1] <= t:
        h += 1
    dp = 0.0
    dv = 0.0
    vsum = 0.0
    hold_s = hold_us * 1e-6
    unknown_us = 0
    unknown = False
    while t < t_end:
        if hn - h < 1:
            return -1, 0, False, 0.0, 0.0, 0.0
        t_h = ht[h]
        f = hf[h]
        has_nxt = hn - h > 1
        nxt = ht[h + 1] if has_nxt else 0
        seg_end = t_end if not has_nxt or nxt > t_end else nxt
        held_end = t_h + hold_us
        if t > held_end:
            held_end = t
        if seg_end < held_end:
            held_end = seg_end
        tau = (held_end - t) * 1e-6
        if tau > 0.0:
            acc = f - g
            dp += dv * tau + 0.5 * acc * tau * tau
            dv += acc * tau
            m = tau if tau > iv_s else iv_s
            if hold_s < m:
                m = hold_s
            vsum += scatter * tau * m
        tau = (seg_end - held_end) * 1e-6
        if tau > 0.0:
            acc = 0.0
            dp += dv * tau + 0.5 * acc * tau * tau
            dv += acc * tau
            vsum += kin_var * tau * kin_tau
            unknown_us += seg_end - held_end
            unknown = True
        t = seg_end
        if has_nxt and nxt <= t_end:
            h += 1
    if h > 0:
        for j in range(hn - h):
            ht[j] = ht[h + j]
            hf[j] = hf[h + j]
        hn -= h
    return hn, unknown_us, unknown, dp, dv, vsum


class EpochBuilder:
    """Samples in, epochs out. One instance per vehicle and boot.

    ``compiled`` (the default) takes the IMU samples and integrates them
    with :func:`imu_kernel`; ``compiled=False`` with the readable reference
    (:meth:`_take_imu_reference`, :meth:`_integrate_reference`), which
    ``tests/test_epochs.py`` holds it to, float for float."""

    def __init__(self, cfg: Config, compiled: bool = True):
        f = cfg.filter
        self._compiled = compiled
        self._f = f
        self._g = f.gravity_mps2
        self._gnss_cfg = cfg.sensors.gnss
        self._rng_sigma = cfg.sensors.rangefinder.sigma_m
        self._rng_scale = cfg.sensors.rangefinder.scale_sigma_frac
        self._baro_cfg = cfg.sensors.baro
        self._model = Model.from_config(cfg)
        # paper mode is the paper's filter: no measured input noise beyond its model
        self._measured_noise = cfg.monitor.mode != "paper"
        self.counters: Counter[str] = Counter()
        # q_a(T)^2 by T: the IMU scatter takes it off for every sample, at a handful of distinct T
        self._q2_by_tau: dict[float, float] = {}
        # _latency_us by (baro interval, the stream's interval)
        self._latency_by_iv: dict[tuple, int] = {}
        m = self._model
        # imu_kernel's constants, as the reference reads them
        self._kparams = (float(self._g), float(f.imu_hold_max_s), float(f.imu_hold_intervals),
                         float(f.kinematic_accel_sigma_mps2 ** 2), float(f.kinematic_accel_tau_s),
                         float(f.imu_scatter_window_s), m.accel_noise_form == "printed", float(m.sigma_a_mps2),
                         float(m.alpha_a_per_s))
        self.reset()

    def reset(self) -> None:
        # IMU samples not yet taken (see _take_imu): times and specific forces
        self._raw_t: list[int] = []
        self._raw_f: list[float] = []
        # or, before them, samples lo .. hi - 1 of an IMU run's array columns
        # (``[t_arr, f_arr, lo, hi]``, see :meth:`_on_imu_run`): the kernel takes
        # them as views, no list between (only while ``_raw_t`` is empty)
        self._span: Optional[list] = None
        # the samples taken, of which the first holds at the last epoch: a deque of
        # (t_us, f_up) for the reference, arrays (_ht, _hf)[:_hn] for the kernel
        self._imu: deque[tuple[int, float]] = deque()
        self._ht = np.empty(64, np.int64)
        self._hf = np.empty(64, np.float64)
        self._hn = 0
        self._ks = np.full(1, math.nan)  # the kernel's scatter variance
        self._ki = np.zeros(_KI_RING + _CADENCE_N, np.int64)  # and its integer state
        self._last_imu_t: Optional[int] = None
        self._epoch_t: Optional[int] = None  # None until started
        self._pending_baro: deque[BaroHeight] = deque()
        self._last_baro: Optional[BaroHeight] = None
        self._aux: dict[str, deque] = {"gnss": deque(), "rng": deque()}
        self._baro_restart = False
        self._cadence = {k: Cadence() for k in ("imu", "baro", "gnss", "rng")}
        self._imu_cadence = self._cadence["imu"]
        self._baro_cadence = self._cadence["baro"]
        self._gap_key: Optional[int] = -1  # the baro interval _gap_us was computed for (-1: none yet)
        self._gap_us = 0
        self._scatter_var = math.nan  # of f_up between consecutive IMU samples, (m/s^2)^2
        self._scatter_n = 0
        self._baro_d2: deque[float] = deque(maxlen=self._baro_cfg.white_window)  # |second differences|
        self._baro_d2_sorted: list[float] = []  # the same, in order (None once a NaN came: sorted() each time)
        self._baro_d2_gm: deque[float] = deque(maxlen=self._baro_cfg.white_window)  # modelled u's share, m^2
        self._baro_last2: deque[float] = deque(maxlen=2)
        self._baro_last2_t: deque[int] = deque(maxlen=2)
        c = self._baro_cfg
        self.baro_white_var_m2 = min(max(c.white_prior_m, c.white_min_m), c.white_max_m) ** 2  # until measured
        self.last_dv_var_m2ps2 = 0.0

    @property
    def started(self) -> bool:
        return self._epoch_t is not None

    # ------------------------------------------------------------------ cadence-derived limits

    def _interval_s(self, kind: str) -> float:
        iv = self._cadence[kind].interval_us
        return 0.0 if iv is None else iv * 1e-6

    def _max_gap_us(self) -> int:
        iv = self._cadence["baro"].interval_us
        if iv != self._gap_key:  # once per change of the baro cadence, not per IMU sample
            f = self._f
            if iv is None:  # not yet shown its cadence
                self._gap_us = int(1e6 * max(f.max_epoch_gap_s, f.max_meas_age_s))
            else:
                self._gap_us = int(1e6 * max(f.max_epoch_gap_s, f.epoch_gap_intervals * self._interval_s("baro")))
            self._gap_key = iv
        return self._gap_us

    def _latency_us(self, which: str) -> int:
        key = (self._cadence["baro"].interval_us, self._cadence[which].interval_us)
        lim_us = self._latency_by_iv.get(key)
        if lim_us is None:  # once per pair of cadences (they change seldom)
            if len(self._latency_by_iv) >= 1024:  # jittery clocks: bounded
                self._latency_by_iv.clear()
            f = self._f
            lim = max(f.max_meas_latency_s,
                      f.meas_latency_intervals * (self._interval_s("baro") + self._interval_s(which)))
            lim_us = self._latency_by_iv[key] = int(1e6 * min(lim, f.max_meas_age_s))
        return lim_us

    def _hold_s(self) -> float:
        f = self._f
        return max(f.imu_hold_max_s, f.imu_hold_intervals * self._interval_s("imu"))

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

    def _q2(self, tau: float) -> float:
        """``accel_noise_q(tau)^2``, computed once per distinct ``tau``."""
        q2 = self._q2_by_tau.get(tau)
        if q2 is None:
            if len(self._q2_by_tau) >= 1024:  # jittery clocks: bounded
                self._q2_by_tau.clear()
            q2 = self._q2_by_tau[tau] = accel_noise_q(tau, self._model) ** 2
        return q2

    def _on_imu(self, t_us: int, f_up: float) -> list[Epoch]:
        # One call per IMU sample (200-400 Hz onboard), so it does the least:
        # the sample waits in ``_raw`` and its scatter, cadence and hold are
        # computed in one pass (:meth:`_take_imu`) when an epoch needs them.
        last_t = self._last_imu_t
        if last_t is not None and t_us <= last_t:
            self.counters["imu_not_increasing"] += 1
            return []
        self._last_imu_t = t_us
        if self._span is not None:
            self._span_to_lists()
        raw = self._raw_t
        raw.append(t_us)
        self._raw_f.append(f_up)
        epoch_t = self._epoch_t
        if epoch_t is None:  # not started: only the latest sample is kept
            if len(raw) >= _RAW_MAX:
                self._take_imu()
            return []
        pending = self._pending_baro
        if pending:
            if pending[0].t_us > t_us:
                return []
        elif t_us - epoch_t <= (self._gap_us if self._baro_cadence.interval_us == self._gap_key  # _max_gap_us()
                                else self._max_gap_us()):
            if len(raw) >= _RAW_MAX:
                self._take_imu()
            return []
        out: list[Epoch] = []
        while pending and pending[0].t_us <= t_us:
            out.append(self._epoch_at(pending.popleft()))
        if not pending and t_us - self._epoch_t > self._max_gap_us():
            out.append(self._forced_epoch(t_us))
        return out

    def _on_imu_run(self, ts: list, fs: list, i: int, j: int, t_arr=None, f_arr=None) -> tuple[int, list[Epoch]]:
        """:meth:`_on_imu` over the samples ``ts[i:j]``, ``fs[i:j]`` (times
        strictly increasing), up to the first that completes an epoch:
        ``(k, epochs)``, samples ``i .. k - 1`` taken and the epochs the last
        of them completed (at most ``_RAW_MAX`` samples per call). The same
        state and epochs as :meth:`_on_imu` sample by sample
        (``tests/test_ingest_imu_runs.py``). ``t_arr``, ``f_arr``: the same
        columns as int64 and float64 arrays, if there are any; the samples
        then wait as a span of them (views for :meth:`_imu_pass`) while
        they follow one another in the columns."""
        last_t = self._last_imu_t
        if last_t is not None and ts[i] <= last_t:  # not increasing: counted, as one sample
            return i + 1, self._on_imu(ts[i], fs[i])
        if j - i > _RAW_MAX:
            j = i + _RAW_MAX
        epoch_t = self._epoch_t
        pending = self._pending_baro
        if epoch_t is None:
            k = j + 1  # not started: no epoch
        elif pending:  # the first sample at or after the head baro completes its epoch
            k = bisect_left(ts, pending[0].t_us, i, j) + 1
        else:  # the first sample beyond the gap limit forces one
            # (_max_gap_us(), its kept value while the baro cadence stays)
            gap_us = self._gap_us if self._baro_cadence.interval_us == self._gap_key else self._max_gap_us()
            k = bisect_right(ts, epoch_t + gap_us, i, j) + 1
        ends = k <= j
        if not ends:
            k = j
        span = self._span
        if span is not None and span[0] is t_arr and span[3] == i:
            span[3] = k  # the next samples of the same columns
        elif t_arr is not None and not self._raw_t and span is None:
            self._span = span = [t_arr, f_arr, i, k]
        else:
            if span is not None:
                self._span_to_lists()
                span = None
            self._raw_t += ts[i:k]
            self._raw_f += fs[i:k]
        t_us = ts[k - 1]
        self._last_imu_t = t_us
        if not ends:
            if not pending and (span[3] - span[2] if span is not None else len(self._raw_t)) >= _RAW_MAX:
                self._take_imu()
            return k, []
        out: list[Epoch] = []
        while pending and pending[0].t_us <= t_us:
            out.append(self._epoch_at(pending.popleft()))
        if not pending and t_us - self._epoch_t > self._max_gap_us():
            out.append(self._forced_epoch(t_us))
        return k, out

    def _span_to_lists(self) -> None:
        """The samples waiting as a span of run columns moved into ``_raw_t``/``_raw_f``
        (which are empty while there is a span), in order."""
        t_arr, f_arr, lo, hi = self._span
        self._span = None
        self._raw_t += t_arr[lo:hi].tolist()
        self._raw_f += f_arr[lo:hi].tolist()

    def _take_imu(self) -> None:
        """Take the IMU samples waiting in ``_raw_t``/``_raw_f`` (see :meth:`_take_imu_reference`)."""
        if self._compiled:
            if self._raw_t or self._span is not None:
                self._imu_pass(False, 0)
        else:
            self._take_imu_reference()

    def _imu_pass(self, integrate: bool, t_end: int) -> tuple[float, float, float]:
        """:func:`imu_kernel` over the samples waiting and those held."""
        rt, rf = self._raw_t, self._raw_f
        span = self._span
        if span is not None:  # (``rt`` empty): views of the run's columns, the values np.fromiter gives
            self._span = None
            t_arr, f_arr, lo, hi = span
            at, af = t_arr[lo:hi], f_arr[lo:hi]
        else:
            n = len(rt)
            at, af = np.fromiter(rt, np.int64, n), np.fromiter(rf, np.float64, n)  # np.array's values, sooner
        need = self._hn + at.shape[0]
        if need > self._ht.shape[0]:
            cap = max(2 * self._ht.shape[0], need)
            ht, hf = np.empty(cap, np.int64), np.empty(cap, np.float64)
            ht[:self._hn] = self._ht[:self._hn]
            hf[:self._hn] = self._hf[:self._hn]
            self._ht, self._hf = ht, hf
        hn, unknown_us, unknown, dp, dv, var = imu_kernel(
            at, af, self._ht, self._hf, self._hn, self._ks, self._ki,
            self._epoch_t is not None, integrate, self._epoch_t if integrate else 0, t_end, *self._kparams)
        rt.clear()
        rf.clear()
        if hn < 0:
            raise IndexError("no IMU sample to integrate from")
        self._hn = hn
        if unknown:
            self.counters["imu_unknown_us"] += unknown_us
        return dp, dv, var

    def _take_imu_reference(self) -> None:
        """Take the IMU samples waiting in ``_raw_t``/``_raw_f``, in order: each one's
        scatter against the previous sample (beyond the modelled INS white
        noise, whose per-sample variance q_a(T)^2 the filters' process noise
        already carries; the running mean may go negative, it is used clamped
        at 0), the IMU cadence, and the hold queue (only the latest sample
        before the first epoch)."""
        if self._span is not None:
            self._span_to_lists()
        raw = list(zip(self._raw_t, self._raw_f))
        if not raw:
            return
        imu = self._imu
        cadence = self._imu_cadence
        q2 = self._q2_by_tau
        window_s = self._f.imu_scatter_window_s
        var = self._scatter_var
        n = self._scatter_n
        prev_t, prev_f = imu[-1] if imu else (None, 0.0)
        # the IMU cadence (Cadence.push), inline
        c_last = cadence._last_t
        dts = cadence._dts
        c_max = dts.maxlen
        interval_us = cadence.interval_us
        for t_us, f_up in raw:
            if prev_t is not None:
                tau = (t_us - prev_t) * 1e-6
                iv = (0.0 if interval_us is None else interval_us * 1e-6) or tau
                qt = q2.get(tau)
                if qt is None:
                    qt = self._q2(tau)
                qi = q2.get(iv)
                if qi is None:
                    qi = self._q2(iv)
                d2 = 0.5 * (f_up - prev_f) ** 2 - 0.5 * (qt + qi)
                n += 1
                if var != var:
                    var = d2
                else:  # a running mean until the window is full, then exponential
                    a = min(1.0, max((t_us - prev_t) * 1e-6 / window_s, 1.0 / n))
                    var += a * (d2 - var)
            if c_last is not None and t_us > c_last:
                dt = t_us - c_last
                if len(dts) == c_max and dts[0] == dt:
                    dts.append(dt)  # the interval that leaves is the one that comes: same median
                else:
                    dts.append(dt)
                    interval_us = sorted(dts)[len(dts) // 2]
            c_last = t_us
            prev_t, prev_f = t_us, f_up
        cadence._last_t = c_last
        cadence.interval_us = interval_us
        self._scatter_var = var
        self._scatter_n = n
        imu.extend(raw)
        self._raw_t.clear()
        self._raw_f.clear()
        if self._epoch_t is None:  # not started
            while len(imu) > 1:
                imu.popleft()  # keep only the latest until the first baro

    def _is_repeat(self, b: BaroHeight) -> bool:
        last = self._last_baro
        return (last is not None and b.pressure_pa == last.pressure_pa and b.height_ref_m == last.height_ref_m
                and (b.t_us - last.t_us) * 1e-6 <= self._f.baro_repeat_max_s)

    def _on_baro(self, b: BaroHeight) -> list[Epoch]:
        if not self.started:
            if self._last_imu_t is None:
                self.counters["baro_before_imu"] += 1
                return []
            self._take_imu()  # before the start: only the latest sample holds
            self._epoch_t = b.t_us
            self._last_baro = b
            self._cadence["baro"].push(b.t_us)
            self._baro_restart = False
            self.counters["starts"] += 1
            return [EpochStart(t_us=b.t_us, baro_m=b.height_ref_m)]
        last_t = self._pending_baro[-1].t_us if self._pending_baro else self._epoch_t
        if b.t_us <= last_t:
            self.counters["baro_late"] += 1
            return []
        if self._is_repeat(b):
            self.counters["baro_repeated"] += 1
            return []
        self._last_baro = b
        self._cadence["baro"].push(b.t_us)
        self._baro_noise(b.height_ref_m, b.t_us)
        self._pending_baro.append(b)
        out: list[Epoch] = []
        # Ready when IMU data covers it; or at once when the IMU has gone quiet.
        while self._pending_baro:
            head = self._pending_baro[0]
            if head.t_us <= self._last_imu_t:
                out.append(self._epoch_at(self._pending_baro.popleft()))
            elif b.t_us - self._last_imu_t > self._max_gap_us():
                self.counters["imu_stale_epochs"] += 1
                out.append(self._epoch_at(self._pending_baro.popleft()))
            else:
                break
        return out

    def _gm_d2_var_m2(self, t_us: int) -> float:
        """Variance of the second difference ending at ``t_us`` that the
        modelled Gauss-Markov baro noise ``u`` alone produces: with
        ``phi_i = exp(-gamma_bb T_i)`` over the two intervals,
        ``sigma_bb^2 (6 - 4 phi_1 - 4 phi_2 + 2 phi_1 phi_2)``."""
        c = self._baro_cfg
        t0, t1 = self._baro_last2_t
        p1 = math.exp(-c.gamma_bb_per_s * (t1 - t0) * 1e-6)
        p2 = math.exp(-c.gamma_bb_per_s * (t_us - t1) * 1e-6)
        return c.sigma_bb_m ** 2 * (6.0 - 4.0 * p1 - 4.0 * p2 + 2.0 * p1 * p2)

    def _baro_noise(self, h_m: float, t_us: int) -> None:
        """Update the baro white-noise estimate: the robust spread (median
        absolute second difference / 0.6745) of the last samples, whose
        variance is 6 sigma^2 for white noise; vehicle motion adds little at
        baro rates and a step or a spike moves a median by one sample.

        The filters already model the Gauss-Markov noise ``u`` (``sigma_bb``,
        ``gamma_bb``), which also moves second differences; its share (the
        mean over the window of :meth:`_gm_d2_var_m2`, / 6) is taken off the
        measured variance, clamped at 0, so only the white noise beyond the
        model is passed on. Both are Gaussian and independent, so the robust
        spread measures the sum of their variances."""
        c = self._baro_cfg
        last = self._baro_last2
        if len(last) == 2:
            d2 = abs(h_m - 2.0 * last[1] + last[0])
            d2s = self._baro_d2_sorted
            if d2s is not None:
                if d2 != d2:
                    self._baro_d2_sorted = d2s = None
                else:
                    if len(self._baro_d2) == self._baro_d2.maxlen:
                        del d2s[bisect_left(d2s, self._baro_d2[0])]  # the one that leaves
                    insort(d2s, d2)
            self._baro_d2.append(d2)
            self._baro_d2_gm.append(self._gm_d2_var_m2(t_us))
            n = len(self._baro_d2)
            if n >= 5:
                s = (sorted(self._baro_d2) if d2s is None else d2s)[n // 2] / 0.6745
                v_model = sum(self._baro_d2_gm) / n
                # white noise beyond the model only when the data show it: once
                # the window is full, the measured variance must exceed what the
                # model's u alone gives at the BARO_WHITE_Z quantile of the
                # estimate, else it is 0; while it fills, the estimate as it
                # stands (before it, the prior: a baro not yet measured is no
                # clean one; with no white noise passed, a noisy baro's first
                # rows set the speed of a vehicle at rest)
                nu = n / _MEDIAN_VAR_REL_SE ** 2
                filling = n < self._baro_d2.maxlen
                significant = filling or s * s > chi2_ratio_quantile(nu, BARO_WHITE_Z) * v_model
                var = max(s * s - v_model, 0.0) / 6.0 if significant else 0.0
                sigma = min(max(math.sqrt(var), c.white_min_m), c.white_max_m)
                self.baro_white_var_m2 = sigma * sigma
        last.append(h_m)
        self._baro_last2_t.append(t_us)

    def _on_aux(self, s, which: str) -> None:
        self.counters[f"{which}_in"] += 1
        if not self.started:
            self.counters[f"{which}_before_start"] += 1
            return
        self._cadence[which].push(s.t_us)
        if s.t_us < self._epoch_t - self._latency_us(which):
            self.counters[f"{which}_late"] += 1
            return
        q = self._aux[which]
        if len(q) >= 64:  # bounded: a stream far ahead of the baro clock
            q.popleft()
            self.counters[f"{which}_superseded"] += 1
        q.append(s)

    # ------------------------------------------------------------------ epochs

    def _integrate_to(self, t_end: int) -> tuple[float, float, float]:
        """Zero-order-hold integral of ``f_up - g`` from the last epoch to
        ``t_end``: ``(dp, dv, dv_var)`` (see :meth:`_integrate_reference`)."""
        if self._compiled:
            return self._imu_pass(True, t_end)
        return self._integrate_reference(t_end)

    def _integrate_reference(self, t_end: int) -> tuple[float, float, float]:
        """Zero-order-hold integral of ``f_up - g`` from the last epoch to
        ``t_end``: ``(dp, dv, dv_var)``. A sample holds for at most the hold
        limit; beyond it the acceleration is unknown (zero mean)."""
        self._take_imu_reference()
        g = self._g
        t = self._epoch_t
        imu = self._imu
        hold_us = int(self._hold_s() * 1e6)
        iv = self._interval_s("imu")
        scatter = 0.0 if self._scatter_var != self._scatter_var else max(self._scatter_var, 0.0)
        kin_var = self._f.kinematic_accel_sigma_mps2 ** 2
        kin_tau = self._f.kinematic_accel_tau_s
        # samples at or before t (lagging ones) only take over the hold
        while len(imu) > 1 and imu[1][0] <= t:
            imu.popleft()
        dp = dv = var = 0.0
        hold_s = hold_us * 1e-6
        unknown_us = 0
        unknown = False
        n_imu = len(imu)
        while t < t_end:
            t_h, f = imu[0]
            if n_imu > 1:
                nxt = imu[1][0]
                seg_end = t_end if nxt > t_end else nxt
            else:
                nxt = None
                seg_end = t_end
            # min(seg_end, max(t, t_h + hold_us)): the held part, then the unknown rest
            held_end = t_h + hold_us
            if t > held_end:
                held_end = t
            if seg_end < held_end:
                held_end = seg_end
            tau = (held_end - t) * 1e-6
            if tau > 0.0:
                acc = f - g
                dp += dv * tau + 0.5 * acc * tau * tau
                dv += acc * tau
                m = tau if tau > iv else iv  # min(max(iv, tau), hold_s)
                if hold_s < m:
                    m = hold_s
                var += scatter * tau * m
            tau = (seg_end - held_end) * 1e-6
            if tau > 0.0:
                acc = 0.0
                dp += dv * tau + 0.5 * acc * tau * tau
                dv += acc * tau
                var += kin_var * tau * kin_tau
                unknown_us += seg_end - held_end
                unknown = True
            t = seg_end
            if nxt is not None and nxt <= t_end:
                imu.popleft()
                n_imu -= 1
        if unknown:
            self.counters["imu_unknown_us"] += unknown_us
        return dp, dv, var

    def _aux_for(self, which: str, t_us: int) -> Optional[AuxMeasurement]:
        """Every pending sample of ``which`` not after ``t_us``, averaged into one measurement."""
        q = self._aux[which]
        if not q or q[0].t_us > t_us:  # nothing pending for this epoch (most epochs)
            return None
        limit = self._latency_us(which)
        n = n_v = 0
        sum_h = sum_age = sum_var = sum_v = 0.0
        while q and q[0].t_us <= t_us:
            s = q.popleft()
            age_us = t_us - s.t_us
            if age_us > limit:
                self.counters[f"{which}_late"] += 1
                continue
            if which == "gnss":
                c = self._gnss_cfg
                if c.use_v_acc and s.sigma_m is not None:
                    sigma = max(s.sigma_m, c.v_acc_floor_m)
                else:
                    sigma = c.sigma_z_m
                h = s.height_ref_m
                if s.vel_up_mps is not None:
                    n_v += 1
                    sum_v += s.vel_up_mps
            else:
                h = s.height_agl_m
                sigma = math.hypot(self._rng_sigma, self._rng_scale * h) if self._rng_scale else self._rng_sigma
            n += 1
            sum_h += h
            sum_age += age_us * 1e-6
            sum_var += sigma * sigma
        if n == 0:
            return None
        self.counters[f"{which}_used"] += n
        if n > 1:
            self.counters[f"{which}_averaged"] += n
        return AuxMeasurement(height_m=sum_h / n, sigma_m=math.sqrt(sum_var / (n * n)), age_s=sum_age / n,
                              vel_up_mps=sum_v / n_v if n_v else math.nan)

    def _make(self, t_us: int, baro_m: Optional[float]) -> EpochInputs:
        dp, dv, dv_var = self._integrate_to(t_us)
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
            dv_var_m2ps2=dv_var if self._measured_noise else 0.0,
            baro_white_var_m2=self.baro_white_var_m2 if baro_m is not None and self._measured_noise else 0.0,
        )
        self.last_dv_var_m2ps2 = dv_var
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
