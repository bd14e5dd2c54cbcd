"""What each fault does to a sensor value: one implementation for every way in.

The simulator (:mod:`.simulate`) changes sensor series before they are
encoded, the tlog injector (:mod:`.inject`) changes MAVLink fields, and
``--inject`` on ``replay``/``audit``/``run`` changes normalised samples
(:class:`SampleFaults`). All three take the value change from here:

* :func:`height_error_m`: the metres a ``gnss_*``/``baro_*`` step, ramp or
  noise burst adds at a time (``accel_bias_step``: m/s^2 on the vertical
  specific force);
* :func:`keeps` (``rate_drop``): whether the n-th message of a stream survives;
* :func:`spikes` (``rng_spikes``): whether this reading gets the spike;
* holds (``baro_freeze``, ``rng_stuck`` without magnitude, ``gnss_dropout``):
  the last value before the window, kept by the caller.

:class:`SampleFaults` is a pure fold over samples (time from the samples
only). A fault's onset and end are on the vehicle clock of the boot in which
its onset is first reached (or the ``boot`` it names), as for ``mavnav
inject``. Per kind, on samples:

* ``gnss_step``/``gnss_ramp``/``gnss_noise``: height and altitude shifted;
  ``gnss_dropout``: the samples vanish (with ``nofix`` the receiver still
  talks but reports no fix, which the source filters: the same for the
  estimator).
* ``baro_step``/``baro_ramp``: height shifted, pressure moved to match;
  ``baro_freeze``: the last sample's pressure and height repeat.
* ``accel_bias_step``: ``f_up_mps2`` shifted.
* ``rng_stuck``: the last reading repeats (or the reading is ``magnitude``);
  ``rng_spikes``: ``magnitude`` added to a random fraction;
  ``rng_out_of_range``: readings beyond the sensor's maximum;
  ``rng_dropout``: readings flagged invalid (or none, ``silent``). A reading
  outside the sensor's limits becomes the same refusal the source would
  have made (:class:`~mavnav.samples.Rejected`, ``sensor=RANGE_STREAM``).
* ``rate_drop``: per stream, one sample in ``round(1/magnitude)`` kept.
* ``link_loss``: nothing in the window; ``LinkLost`` at its first sample and
  ``LinkRecovered`` at the first after it.
* ``reboot``: nothing in the window; then a ``Reboot`` and vehicle time
  restarted (shifted back by the onset), boot counted up.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Dict, Iterable, Iterator, List, Optional, Sequence

import numpy as np

from ..atmosphere import pressure_at_height_pa
from ..samples import (
    AutopilotHeight,
    BaroHeight,
    GnssHeight,
    LinkLost,
    LinkRecovered,
    RangeHeight,
    Reboot,
    Rejected,
    SpecificForceUp,
)
from ..ingest.onboard.imurun import ImuRun
from ..sensors import AUTOPILOT_STREAM, BARO_STREAM, GNSS_STREAM, IMU_STREAM, RANGE_STREAM
from .scenario import Fault


def height_error_m(fault: Fault, t_s, rng: Optional[np.random.Generator] = None):
    """The error a step/ramp/noise fault (or ``accel_bias_step``) adds at ``t_s``
    inside its window: metres (m/s^2 for the accelerometer). ``t_s`` may be
    a float or an array (one draw per element for ``gnss_noise``)."""
    k = fault.kind
    if k.endswith("_ramp"):
        return fault.magnitude * (t_s - fault.onset_s)
    if k == "gnss_noise":
        draw = rng.standard_normal(np.shape(t_s)) if np.ndim(t_s) else float(rng.standard_normal())
        return fault.magnitude * draw
    return float(fault.magnitude) if not np.ndim(t_s) else np.full(np.shape(t_s), float(fault.magnitude))


def keeps(fault: Fault, n):
    """``rate_drop``: whether the n-th message (0-based; int or array) of a stream in the window is sent."""
    keep_every = max(1, int(round(1.0 / fault.magnitude)))
    return n % keep_every == 0


def spikes(fault: Fault, rng: np.random.Generator, n: Optional[int] = None):
    """``rng_spikes``: whether this reading (or each of ``n``) gets the spike."""
    if n is None:
        return bool(rng.random() < fault.effective_probability)
    return rng.random(n) < fault.effective_probability


def out_of_range_reading_m(fault: Fault, max_m: float) -> float:
    """``rng_out_of_range``: the reading reported beyond the sensor's maximum."""
    return max_m + (1.0 if fault.magnitude is None else fault.magnitude)


class _State:
    def __init__(self, fault: Fault, index: int):
        self.fault = fault
        self.boot = fault.boot
        self.rng = np.random.default_rng([fault.seed, index])
        self.counters: Dict[str, int] = {}
        self.held: Dict[str, object] = {}
        self.inside = False
        self.dropped = 0
        self.modified = 0


_KIND = {SpecificForceUp: IMU_STREAM, BaroHeight: BARO_STREAM, GnssHeight: GNSS_STREAM, RangeHeight: RANGE_STREAM,
         AutopilotHeight: AUTOPILOT_STREAM}


class SampleFaults:
    """Apply faults to a stream of normalised samples (``feed`` one, get what follows)."""

    def __init__(self, faults: Sequence[Fault]):
        self.states = [_State(f, i) for i, f in enumerate(faults)]
        self._last: Dict[str, object] = {}  # last original sample per kind (for holds)
        self._boot_in = 0  # boot of the incoming samples
        self._shift_us = 0  # reboot faults: vehicle time removed after the window
        self._boots_added = 0
        self._last_t_us: Optional[int] = None

    def apply(self, samples: Iterable[object]) -> Iterator[object]:
        for s in samples:
            yield from self.feed(s)

    def report(self) -> List[dict]:
        return [{"kind": st.fault.kind, "boot": st.boot, "samples_modified": st.modified,
                 "samples_dropped": st.dropped} for st in self.states]

    # ------------------------------------------------------------------

    def feed(self, s) -> List[object]:
        """What follows from one sample: itself (changed or not), nothing, or events."""
        out = self._feed(s)
        kind = _KIND.get(type(s))
        if kind is not None:
            self._last[kind] = s  # the original: holds repeat the last value before the window
        return out

    def _feed(self, s) -> List[object]:
        t_us = getattr(s, "t_us", None)
        boot = getattr(s, "boot", None)
        if isinstance(s, Reboot):
            self._boot_in = s.boot
        if t_us is None or boot is None:
            return [self._moved(s)]
        t_s = t_us * 1e-6
        out: List[object] = []
        active = []
        for st in self.states:
            f = st.fault
            if st.boot is None and boot == self._boot_in and t_s >= f.onset_s:
                st.boot = boot
            now = st.boot == boot and f.onset_s <= t_s < f.end_s
            if st.inside and not now:
                out.extend(self._leave(st, s))
            st.inside = now
            if now:
                active.append(st)
        kind = _KIND.get(type(s))
        if kind is not None:
            self._last_t_us = t_us
        for st in active:
            k = st.fault.kind
            if k in ("link_loss", "reboot"):
                if st.dropped == 0 and k == "link_loss":
                    out.append(LinkLost(recv_s=s.recv_s, silent_s=max(0.0, t_s - st.fault.onset_s)))
                st.dropped += 1
                return out
            if kind is None:
                continue
            s = self._effect(st, kind, s)
            if s is None:
                return out
        out.append(self._moved(s))
        return out

    def _leave(self, st: _State, s) -> List[object]:
        k = st.fault.kind
        if k == "link_loss" and st.dropped:
            return [LinkRecovered(recv_s=s.recv_s, outage_s=st.fault.end_s - st.fault.onset_s)]
        if k == "reboot":
            last = self._last_t_us if self._last_t_us is not None else 0
            self._shift_us += int(round(st.fault.onset_s * 1e6))
            self._boots_added += 1
            new_t = max(0, s.t_us - self._shift_us)
            return [Reboot(t_us=new_t, recv_s=s.recv_s, boot=s.boot + self._boots_added,
                           last_t_us=max(0, last - (self._shift_us - int(round(st.fault.onset_s * 1e6)))))]
        return []

    def _moved(self, s):
        """Vehicle time and boot after injected reboots."""
        if not self._boots_added or isinstance(s, (LinkLost, LinkRecovered)):
            return s
        ch = {}
        if getattr(s, "t_us", None) is not None:
            ch["t_us"] = max(0, s.t_us - self._shift_us)
        if getattr(s, "boot", None) is not None and not isinstance(s, Reboot):
            ch["boot"] = s.boot + self._boots_added
        return dataclasses.replace(s, **ch) if ch else s

    def _effect(self, st: _State, kind: str, s):
        f = st.fault
        k = f.kind
        t_s = s.t_us * 1e-6
        if k == "rate_drop":
            n = st.counters.get(kind, 0)
            st.counters[kind] = n + 1
            if keeps(f, n):
                return s
            st.dropped += 1
            return None
        if kind == GNSS_STREAM and k.startswith("gnss_"):
            if k == "gnss_dropout":
                st.dropped += 1
                return None
            dh = height_error_m(f, t_s, st.rng)
            st.modified += 1
            return dataclasses.replace(s, height_ref_m=s.height_ref_m + dh, alt_m=s.alt_m + dh)
        if kind == BARO_STREAM and k.startswith("baro_"):
            st.modified += 1
            if k == "baro_freeze":
                held = st.held.setdefault(BARO_STREAM, self._last.get(BARO_STREAM, s))
                return dataclasses.replace(s, height_ref_m=held.height_ref_m, pressure_pa=held.pressure_pa)
            dh = height_error_m(f, t_s, st.rng)
            p_ref = s.pressure_pa / pressure_at_height_pa(s.height_ref_m, 1.0)
            return dataclasses.replace(s, height_ref_m=s.height_ref_m + dh,
                                       pressure_pa=pressure_at_height_pa(s.height_ref_m + dh, p_ref))
        if kind == IMU_STREAM and k == "accel_bias_step":
            st.modified += 1
            return dataclasses.replace(s, f_up_mps2=s.f_up_mps2 + height_error_m(f, t_s))
        if kind == RANGE_STREAM and k.startswith("rng_"):
            return self._range(st, s)
        return s

    def _range(self, st: _State, s: RangeHeight):
        f = st.fault
        k = f.kind
        cos_t = s.height_agl_m / s.range_m if s.range_m > 0 else 1.0
        if k == "rng_dropout":
            st.dropped += 1
            if f.effective_mode == "silent":
                return None
            return Rejected(s.recv_s, "invalid_quality", f"{s.source} reading flagged invalid (injected)",
                            s.t_us, s.boot, sensor=RANGE_STREAM)
        if k == "rng_stuck":
            if f.magnitude is None:
                held = st.held.setdefault(RANGE_STREAM, self._last.get(RANGE_STREAM, s))
                reading = held.range_m
                cos_t = held.height_agl_m / held.range_m if held.range_m > 0 else 1.0
            else:
                reading = float(f.magnitude)
        elif k == "rng_spikes":
            if not spikes(f, st.rng):
                return s
            reading = s.range_m + f.magnitude
        else:  # rng_out_of_range
            hi = s.max_m if s.max_m == s.max_m else s.range_m
            reading = out_of_range_reading_m(f, hi)
        st.modified += 1
        lo = s.min_m if s.min_m == s.min_m else 0.0
        hi = s.max_m if s.max_m == s.max_m else math.inf
        if not lo <= reading <= hi:
            return Rejected(s.recv_s, "out_of_range", f"{s.source} {reading:.3f} m outside [{lo:g}, {hi:g}] m",
                            s.t_us, s.boot, sensor=RANGE_STREAM)
        return dataclasses.replace(s, range_m=reading, height_agl_m=reading * cos_t)


# faults whose effects touch only their own height sensor's samples (nothing
# of the IMU, the clock or the link): an IMU run passes them unchanged
_HEIGHT_SENSOR_FAULTS = ("gnss_", "baro_", "rng_")


class FaultedSource:
    """A source with faults applied to its samples; ``stats`` and the rest pass through."""

    def __init__(self, source, faults: Sequence[Fault]):
        self.source = source
        self.faults = list(faults)
        self.injector = SampleFaults(self.faults)

    def __getattr__(self, name):
        return getattr(self.source, name)

    def __iter__(self):
        self.injector = inj = SampleFaults(self.faults)
        for s in self.source:
            yield from inj.feed(s)

    def runs(self):
        """The faulted stream with the IMU samples in runs, where the source
        gives runs (an onboard log; :func:`mavnav.pipeline.run` reads them):
        runs pass through whole when no fault can touch an IMU sample (the
        height sensors' faults), else each run goes through the faults sample
        by sample. Either way the samples are those of iterating this source."""
        if not callable(getattr(type(self.source), "runs", None)):
            yield from iter(self)
            return
        self.injector = inj = SampleFaults(self.faults)
        whole = all(f.kind.startswith(_HEIGHT_SENSOR_FAULTS) for f in self.faults)
        for s in self.source.runs():
            if type(s) is not ImuRun:
                yield from inj.feed(s)
            elif whole:
                yield s
            else:
                for x in s.samples(s.lo, s.hi):
                    yield from inj.feed(x)


__all__ = ["height_error_m", "keeps", "spikes", "out_of_range_reading_m", "SampleFaults", "FaultedSource"]
