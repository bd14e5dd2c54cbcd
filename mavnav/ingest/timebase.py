"""The normaliser's time stage: each message's vehicle time, as a stream of steps.

A :class:`TimeBase` owns the vehicle clock (:class:`~.clock.VehicleClock`)
and the other streams' clocks (:class:`~.clock.StreamClocks`). Its entry
points take a message with how it is timed (``time_boot_ms`` of a
component, ``time_usec``, a stream on its own clock, or no time at all) and
return the steps that follow from it, which the normaliser acts on in
order:

* :class:`Placed`: message ``f`` of kind ``what`` is at vehicle time
  ``t_us`` (the normaliser runs its handler for ``what``);
* :data:`SETTLED`: a stream's messages so far are placed (what waits for
  them, the attitudes of IMU samples, may be resolved);
* :class:`NewBoot`: a reboot is confirmed; the normaliser closes the old
  boot (flushing :meth:`TimeBase.flush`), then calls
  :meth:`TimeBase.new_boot`, before the new boot's first message is placed;
* :class:`ClockStepped`: the vehicle clock stepped back (not a reboot);
* :class:`Refused`: a message it cannot place (``stale``, ``time_jump``,
  ``no_time``).

A caller must act on each step before taking the next: where a handler run
for one step can matter to the next (SYSTEM_TIME sets the Unix offset that
places later ``time_usec`` messages), when a candidate time base is adopted
or refuted, the steps are produced lazily, by a generator. The common case,
one message placed at once, is a tuple.

A time far behind the clock (or too far ahead) starts a *candidate* time
base. It is adopted only once at least ``CONFIRM_N`` messages continue it,
with nothing from the old one in between, over ``CONFIRM_SPAN_US`` of their
own time or until they catch up with the old time base (a small step back):
a reboot (behind by ``reboot_jump_s`` or more), a step of the vehicle clock
(behind by less: later times are moved on by the step, so there is one
timeline and nothing is lost), or a jump forward. A message that leaps from
the candidates back to the old time base refutes them: they were stale
packets (a radio's buffer, a late burst after an outage: dropped, counted as
``stale``) or a corrupt time (``time_jump``). While a candidate time base is
open, messages timed otherwise (other components, ``time_usec`` in Unix
time or missing, untimed ones) wait for its verdict (*followers*), so that
the samples right after a reboot land in the new boot.
"""

from __future__ import annotations

from typing import Iterable, Iterator, List, NamedTuple, Optional, Tuple, Union

from .clock import HOLD, UNIX_THRESHOLD_US, StreamClocks, VehicleClock, is_reboot

MAV_COMP_ID_AUTOPILOT1 = 1
BEHIND_US = 300_000  # a vehicle time this far behind the clock starts a candidate time base
CONFIRM_N = 5  # messages on a new time base before it is adopted ...
CONFIRM_SPAN_US = 1_000_000  # ... spanning this much of its time (or catching up), nothing of the old one between
CLOCK_STEP_GAP_US = 1_000  # after a step back, the first new time lands this far after the last old one


# ------------------------------------------------------------------ steps


class Placed(NamedTuple):
    """Message ``f`` of kind ``what`` at vehicle time ``t_us``."""

    t_us: int
    recv_s: float
    what: str
    f: object


class _Settled:
    """A stream's messages so far are placed."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "SETTLED"


SETTLED = _Settled()


class NewBoot(NamedTuple):
    """A reboot: the new boot starts at ``t_us`` (received at ``recv_s``)."""

    t_us: int
    recv_s: float


class ClockStepped(NamedTuple):
    """The vehicle clock stepped back; ``text`` says by how much and what was done."""

    recv_s: float
    text: str


class Refused(NamedTuple):
    """A message the time stage cannot place: ``kind`` ``stale``, ``time_jump`` or ``no_time``."""

    recv_s: float
    kind: str
    detail: str
    t_us: Optional[int] = None


Step = Union[Placed, _Settled, NewBoot, ClockStepped, Refused]


# ------------------------------------------------------------------ what waits


class _Candidate(NamedTuple):
    """A message on a new vehicle time base not yet confirmed."""

    t_us: int
    recv_s: float
    what: str
    f: object


class _UsecKey(NamedTuple):
    """A follower's key for a ``time_usec`` stream."""

    key: tuple  # its StreamClocks key
    name: str  # its name in messages


class _Follower(NamedTuple):
    """A message that waits for the verdict on a new time base: ``key`` None
    (untimed), a :class:`_UsecKey` (a time_usec stream) or a StreamClocks
    key, with its raw time."""

    key: Optional[tuple]
    t_raw: Optional[int]
    recv_s: float
    what: str
    f: object


# ------------------------------------------------------------------ the stage


class TimeBase:
    def __init__(self, reboot_jump_s: float):
        self.clock = VehicleClock(reboot_jump_s)
        self.streams = StreamClocks()
        self.ap_compid = MAV_COMP_ID_AUTOPILOT1  # whose time_boot_ms drives the clock
        self._cands: List[_Candidate] = []  # a new vehicle time base, unconfirmed
        self._followers: List[_Follower] = []

    def boot_ms(self, t_us: int, recv_s: float, compid: int, what: str, f) -> Iterable[Step]:
        """A ``time_boot_ms``-stamped message (``t_us``: that time in us) of component ``compid``."""
        if compid != self.ap_compid:
            # another component's clock: mapped onto ours, never drives it
            return self.stream(("boot_ms", compid, what), t_us, recv_s, what, f)
        clock = self.clock
        t_us += clock.step_us
        if self._cands:
            return self._with_candidates(t_us, recv_s, what, f)
        if clock.classify(t_us, recv_s, BEHIND_US) == HOLD:  # _on_clock, inline: the hot path
            self._cands = [_Candidate(t_us, recv_s, what, f)]
            return ()
        clock.accept(t_us, recv_s)
        return Placed(t_us, recv_s, what, f), SETTLED

    def _on_clock(self, t_us: int, recv_s: float, what: str, f) -> Iterable[Step]:
        """A time of the autopilot's clock with no candidate time base open: placed,
        or the first candidate of a new one."""
        clock = self.clock
        if clock.classify(t_us, recv_s, BEHIND_US) == HOLD:
            self._cands = [_Candidate(t_us, recv_s, what, f)]
            return ()
        clock.accept(t_us, recv_s)
        return Placed(t_us, recv_s, what, f), SETTLED

    def _with_candidates(self, t_us: int, recv_s: float, what: str, f) -> Iterator[Step]:
        """A time of the autopilot's clock while a candidate time base is open: one
        more candidate (which may confirm it), or its refutation."""
        if self._continues_candidates(t_us):
            self._cands.append(_Candidate(t_us, recv_s, what, f))
            if self._candidates_confirmed(t_us):
                yield from self._adopt()
            return
        yield from self._refute(f"then {t_us} us")
        yield from self._on_clock(t_us, recv_s, what, f)

    def usec(self, key: tuple, t_usec: int, recv_s: float, name: str, what: str, f,
             est: Optional[int] = None) -> List[Step]:
        """A ``time_usec`` stream (StreamClocks ``key``, ``name`` in messages): boot
        time, Unix time or none, then :meth:`stream`. Unix and missing times are
        placed by the vehicle clock: while a new time base is unconfirmed they
        wait, and are placed on the one that holds."""
        if self._cands and (t_usec == 0 or t_usec >= UNIX_THRESHOLD_US):
            self._followers.append(_Follower(_UsecKey(key, name), t_usec, recv_s, what, f))
            return []
        t = self.clock.boot_from_usec(t_usec, recv_s)
        if t is None:
            return [Refused(recv_s, "no_time", f"{name}: cannot place time_usec {t_usec} on the vehicle clock")]
        return self.stream(key, t, recv_s, what, f, est)

    def stream(self, key, t_raw: int, recv_s: float, what: str, f, est: Optional[int] = None) -> List[Step]:
        """A time that may be on another clock (``time_usec``, other components): see StreamClocks."""
        if self._cands:
            self._followers.append(_Follower(key, t_raw, recv_s, what, f))
            return []
        off = self.streams.offsets.get(key)
        if off is not None:  # StreamClocks.map, inline: the stream's clock is known (the estimate is not needed)
            return [Placed(t_raw - off, recv_s, what, f), SETTLED]
        if est is None:
            est = self.clock.estimate(recv_s)
        out: List[Step] = [Placed(t_us, frecv, w, ff)
                           for t_us, (w, ff, frecv) in self.streams.map(key, t_raw, est, (what, f, recv_s))]
        out.append(SETTLED)
        return out

    def untimed(self, recv_s: float, what: str, f, name: str) -> List[Step]:
        """A message without a time of its own: placed on the vehicle clock by receive time."""
        if self._cands:
            self._followers.append(_Follower(None, None, recv_s, what, f))
            return []
        t_us = self.clock.estimate(recv_s)
        if t_us is None:
            return [Refused(recv_s, "no_time", f"{name} before any timed message")]
        return [Placed(t_us, recv_s, what, f)]

    def flush(self) -> List[Step]:
        """What the other streams' clocks still hold, placed now (the end of a boot)."""
        return [Placed(t_us, frecv, w, ff) for t_us, (w, ff, frecv) in self.streams.flush()]

    def finish(self) -> Iterator[Step]:
        """The end of the stream: an open candidate time base is refuted."""
        if self._cands:
            yield from self._refute("at the end of the stream")

    def new_boot(self, t_us: int, recv_s: float) -> Tuple[Optional[int], int]:
        """Start the boot of a :class:`NewBoot` step: ``(last time of the old boot, new boot)``."""
        last = self.clock.last_t_us
        boot = self.clock.new_boot(t_us, recv_s)
        self.streams.reset()
        return last, boot

    # ------------------------------------------------------------------ candidates

    def _continues_candidates(self, t_us: int) -> bool:
        """Whether ``t_us`` goes on with the candidate time base (else it refutes it)."""
        cands, last = self._cands, self.clock.last_t_us
        ct0, ct1 = cands[0].t_us, cands[-1].t_us
        if ct0 < last:  # behind: refuted by a leap from the candidates back to the old time base
            back_to_old = t_us >= last - BEHIND_US and t_us - ct1 > BEHIND_US
            return not back_to_old and t_us >= ct1 - BEHIND_US
        return t_us >= ct1 - BEHIND_US  # ahead: refuted by a time back near the old one

    def _candidates_confirmed(self, t_us: int) -> bool:
        """Enough candidates over enough of their time, or caught up with the old time base."""
        cands, last = self._cands, self.clock.last_t_us
        ct0 = cands[0].t_us
        caught_up = ct0 < last and t_us >= last - BEHIND_US
        return len(cands) >= CONFIRM_N and (t_us - ct0 >= CONFIRM_SPAN_US or caught_up)

    def _adopt(self) -> Iterator[Step]:
        cands, self._cands = self._cands, []
        clock = self.clock
        t0, recv0 = cands[0].t_us, cands[0].recv_s
        last = clock.last_t_us
        if is_reboot(last, t0, clock.jump_us):
            yield NewBoot(t0, recv0)
        elif t0 < last:
            step = last - t0 + CLOCK_STEP_GAP_US  # the first new time just after the last old one
            clock.step_us += step
            cands = [c._replace(t_us=c.t_us + step) for c in cands]
            self.streams.reset()  # the other clocks are placed on it again
            yield ClockStepped(recv0, f"vehicle clock stepped back {(last - t0) * 1e-6:.2f} s at {last * 1e-6:.3f} s "
                                      f"(boot {clock.boot}): later times moved on by {step * 1e-6:.2f} s to keep one "
                                      f"timeline")
        else:
            clock.jump_to(t0, recv0)
        for c in cands:
            clock.accept(c.t_us, c.recv_s)
            yield Placed(c.t_us, c.recv_s, c.what, c.f)
        yield from self._release_followers(cands)
        yield SETTLED

    def _refute(self, why: str) -> Iterator[Step]:
        cands, self._cands = self._cands, []
        last = self.clock.last_t_us
        for c in cands:
            t = c.t_us
            if last is not None and t < last:
                yield Refused(c.recv_s, "stale", f"vehicle time {t} us against {last} us, {why}: an isolated old packet",
                              t)
            else:
                yield Refused(c.recv_s, "time_jump", f"vehicle time {t} us against {last} us, {why}", t)
        yield from self._release_followers()

    def _release_followers(self, cands: Optional[List[_Candidate]] = None) -> Iterator[Step]:
        """Release what waited for a verdict on a new time base; after one was adopted
        (``cands``, its messages), their receive times place them on it."""
        followers, self._followers = self._followers, []
        for fl in followers:
            est = _estimate_on(cands, fl.recv_s) if cands else None
            key = fl.key
            if key is None:
                if est is None:
                    yield from self.untimed(fl.recv_s, fl.what, fl.f, "untimed message")
                else:
                    yield Placed(est, fl.recv_s, fl.what, fl.f)
            elif type(key) is _UsecKey:
                yield from self.usec(key.key, fl.t_raw, fl.recv_s, key.name, fl.what, fl.f, est)
            else:
                yield from self.stream(key, fl.t_raw, fl.recv_s, fl.what, fl.f, est)


def _estimate_on(cands: List[_Candidate], recv_s: float) -> int:
    """Vehicle time at ``recv_s`` on the time base of ``cands`` (in order):
    from the latest candidate received by then (the first one for earlier receive times)."""
    t0, r0 = cands[0].t_us, cands[0].recv_s
    for c in cands:
        if c.recv_s <= recv_s:
            t0, r0 = c.t_us, c.recv_s
        else:
            break
    return t0 + int(round((recv_s - r0) * 1e6))


__all__ = ["TimeBase", "Placed", "SETTLED", "NewBoot", "ClockStepped", "Refused", "Step"]
