"""STATUSTEXT for alarm transitions: wording, severity, chunking and a coalescing rate limit.

One message per change of a source's state, ASCII, naming the source:
``mavnav gnss ALARM: <reason>``. A text longer than the field's 50
characters is never cut: it goes out as MAVLink 2 chunks (the same nonzero
``id``, ``chunk_seq`` 0, 1, ...), split between words and padded with spaces
to the full 50 characters, so each chunk is readable on its own and only the
last one, shorter, carries the NUL that marks the end (the protocol's rule);
a text that fits is one message with ``id`` 0. Severity follows the new state:

=====================================  =======================
new state                              MAV_SEVERITY
=====================================  =======================
alarm                                  CRITICAL (2)
unavailable (after having been in use)  ERROR (3)
caution                                WARNING (4)
nominal                                NOTICE (5)  (cleared)
unavailable at start-up                INFO (6), worded STARTING
=====================================  =======================

Start-up is not an error: a source that has not yet been in use in this boot
(no epoch has shown it nominal, caution or alarm) and is unavailable is
*starting* (:class:`StartupWatch`), e.g. ``mavnav rangefinder STARTING: no
recent data`` at INFO; once it has been in use, losing it is an ERROR.

What the input says besides state changes goes out as ``mavnav input ...``
(:func:`input_text`): a vehicle reboot (``VEHICLE REBOOTED: ...``) and a step
of the vehicle clock at NOTICE, the other notices (the vehicle monitored, the
systems ignored, what the source waits for) at INFO. None of them is an
error: the monitor restarts or goes on by itself.

The rate limit is per source, on vehicle time: a source's first change is
sent at once; further changes of the same source within
``min_interval_us`` of its last STATUSTEXT are coalesced into one pending
message that always holds the *latest* state (never dropped) and counts the
changes it swallowed (``(+2)`` in the text). Pending messages go out when
the source's interval has passed, on a reboot (vehicle time restarts), or
at :meth:`StatusTextLimiter.flush` (end of run, link loss). Sources do not
delay one another.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Set, Tuple

from pymavlink.dialects.v20 import common as mavlink2

from ..report import AlarmEvent, EpochReport
from ..samples import Notice, Reboot

MAX_CHARS = 50
PREFIX = "mavnav"
STARTING = "STARTING"

SEVERITY_FOR_STATE = {
    "alarm": mavlink2.MAV_SEVERITY_CRITICAL,
    "unavailable": mavlink2.MAV_SEVERITY_ERROR,
    "caution": mavlink2.MAV_SEVERITY_WARNING,
    "nominal": mavlink2.MAV_SEVERITY_NOTICE,
}
SEVERITY_STARTING = mavlink2.MAV_SEVERITY_INFO
SEVERITY_REBOOT = mavlink2.MAV_SEVERITY_NOTICE
SEVERITY_NOTICE = {"clock_step": mavlink2.MAV_SEVERITY_NOTICE}  # Notice.kind -> severity; INFO otherwise


def severity(event: AlarmEvent, starting: bool = False) -> int:
    """MAV_SEVERITY for a transition, from its new state (INFO for a source still starting)."""
    if starting and event.state == "unavailable":
        return SEVERITY_STARTING
    return SEVERITY_FOR_STATE[event.state]


def _ascii(text: str) -> str:
    return text.encode("ascii", "replace").decode("ascii").replace("\n", " ").replace("\r", " ")


def format_text(event: AlarmEvent, coalesced: int = 0, starting: bool = False) -> str:
    """``mavnav SOURCE STATE[ (+N)]: reason``, whole (see :func:`split_text` for the wire)."""
    word = STARTING if starting and event.state == "unavailable" else event.state.upper()
    head = f"{PREFIX} {event.source} {word}"
    if coalesced:
        head += f" (+{coalesced})"
    reason = _ascii(event.reason.strip())
    text = f"{head}: {reason}" if reason else head
    return " ".join(_ascii(text).split())


def input_text(s) -> Optional[Tuple[int, str]]:
    """``(severity, text)`` for what the input says (a :class:`~mavnav.samples.Reboot`
    or :class:`~mavnav.samples.Notice`), None for anything else."""
    if isinstance(s, Reboot):
        return SEVERITY_REBOOT, (f"{PREFIX} input VEHICLE REBOOTED: its time restarted at {s.t_us * 1e-6:.1f} s "
                                 f"after {s.last_t_us * 1e-6:.1f} s (boot {s.boot}); the monitor starts again")
    if isinstance(s, Notice):
        sev = SEVERITY_NOTICE.get(s.kind, mavlink2.MAV_SEVERITY_INFO)
        return sev, " ".join(_ascii(f"{PREFIX} input {s.text}").split())
    return None


def split_text(text: str, size: int = MAX_CHARS) -> List[str]:
    """``text`` as STATUSTEXT chunks: cut between words (inside a word only if one
    word is longer than a chunk), every chunk but the last padded with spaces to
    exactly ``size`` characters and the last shorter than ``size``. A receiver
    takes the NUL that ends a shorter field for the last chunk (the protocol's
    rule), so only the last may be short; joined, the chunks give ``text`` back
    up to the padding spaces, and each one read alone is whole words."""
    if len(text) <= size:
        return [text]
    chunks: List[str] = []
    rest = text
    while len(rest) >= size:
        cut = rest.rfind(" ", 0, size)
        chunk = rest[: cut + 1] if cut > 0 else rest[:size]
        chunks.append(chunk.ljust(size))
        rest = rest[len(chunk):]
    chunks.append(rest)
    return chunks


class StartupWatch:
    """Which sources have been in use (nominal, caution or alarm in an epoch) in each boot."""

    def __init__(self) -> None:
        self._used: Set[Tuple[int, str]] = set()

    def epoch(self, report: EpochReport) -> None:
        for name, st in report.sources.items():
            if st.state != "unavailable":
                self._used.add((report.boot, name))

    def starting(self, event: AlarmEvent) -> bool:
        """Whether ``event`` is a source still starting up (unavailable, never yet in use)."""
        return event.state == "unavailable" and (event.boot, event.source) not in self._used


@dataclass
class _Pending:
    event: AlarmEvent
    swallowed: int  # changes replaced by a later one before being sent


class StatusTextLimiter:
    """Per-source coalescing rate limit on vehicle time (see the module docstring).

    Each method returns the ``(event, swallowed)`` pairs to send now, in
    vehicle-time order.
    """

    def __init__(self, min_interval_us: int):
        if min_interval_us < 0:
            raise ValueError("min_interval_us must be >= 0")
        self.min_interval_us = int(min_interval_us)
        self._last_sent: Dict[str, Tuple[int, int]] = {}  # source -> (boot, t_us)
        self._pending: Dict[str, _Pending] = {}
        self.coalesced_total = 0

    def _free(self, source: str, boot: int, t_us: int) -> bool:
        last = self._last_sent.get(source)
        if last is None:
            return True
        lboot, lt = last
        return boot != lboot or t_us < lt or t_us - lt >= self.min_interval_us

    def offer(self, event: AlarmEvent) -> List[Tuple[AlarmEvent, int]]:
        out = self.due(event.boot, event.t_us)
        src = event.source
        pend = self._pending.get(src)
        if pend is None and self._free(src, event.boot, event.t_us):
            self._last_sent[src] = (event.boot, event.t_us)
            out.append((event, 0))
            return out
        if pend is None:
            self._pending[src] = _Pending(event, 0)
        else:
            pend.swallowed += 1
            pend.event = event
            self.coalesced_total += 1
        return out

    def due(self, boot: int, t_us: int) -> List[Tuple[AlarmEvent, int]]:
        """Pending messages whose source interval has passed at ``(boot, t_us)``."""
        if not self._pending:
            return []
        ready = [s for s in self._pending if self._free(s, boot, t_us)]
        return self._pop(ready, boot, t_us)

    def flush(self) -> List[Tuple[AlarmEvent, int]]:
        """Every pending message, regardless of the interval."""
        return self._pop(list(self._pending), None, None)

    def _pop(self, sources, boot: Optional[int], t_us: Optional[int]) -> List[Tuple[AlarmEvent, int]]:
        out = []
        for s in sources:
            p = self._pending.pop(s)
            self._last_sent[s] = (p.event.boot, p.event.t_us) if boot is None else (boot, t_us)
            out.append((p.event, p.swallowed))
        out.sort(key=lambda x: (x[0].boot, x[0].t_us))
        return out

    @property
    def pending(self) -> int:
        return len(self._pending)
