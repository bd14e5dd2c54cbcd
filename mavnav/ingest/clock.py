"""The vehicle clock as seen from the ground: boots, Unix-to-boot mapping, untimed messages.

Vehicle time is integer microseconds since the vehicle booted. It is learnt
from the messages that carry a boot-time field; receive time (``recv_s``)
is used only to place messages that carry no time at all.

* **Reboot, clock steps, stale packets.** A boot-time value well behind
  the latest one is held as a *candidate* time base, and so is a forward
  jump larger than the receive time elapsed allows (3x plus 10 s); the
  normaliser confirms it with several messages (see :mod:`.timebase`):
  more than ``reboot_jump_s`` behind is a reboot (the boot index
  increments), less is a step of the vehicle clock (``step_us`` keeps one
  timeline), and a candidate the old time base goes on after was a stale
  or corrupt packet.
* **Unix time.** A ``time_usec`` above 1e15 us (31 years of uptime) is Unix
  time. It is mapped onto boot time with the offset from SYSTEM_TIME when
  the vehicle sends one with a Unix time, else with the receive-time offset
  of the latest boot-time message (ground clock ~ GNSS time).
* **No time field** (RANGEFINDER, or a zero ``time_usec``): the latest
  boot-time value plus the receive time elapsed since it arrived, so the
  estimate never runs backwards and follows the vehicle clock even when the
  ground clock is skewed.
"""

from __future__ import annotations

from typing import Optional

UNIX_THRESHOLD_US = 1_000_000_000_000_000


def is_reboot(last: float, t: float, jump: float) -> bool:
    """The reboot rule, written once: a vehicle time ``t`` more than ``jump``
    behind the latest one, ``last``, is a new boot; less is a step of the
    vehicle clock (or jitter). All three in one unit (us here, s in the fault
    injector). ``jump`` is ``ingest.reboot_jump_s`` (default
    :data:`mavnav.config.REBOOT_JUMP_S`). The normaliser applies it once
    several messages confirm the new time base (:mod:`.timebase`); the fault
    injector, which follows a recorded log, on each message."""
    return t < last - jump

ACCEPT = 0
HOLD = 1


class VehicleClock:
    def __init__(self, reboot_jump_s: float):
        self.jump_us = int(reboot_jump_s * 1e6)
        self.boot = 0
        self.last_t_us: Optional[int] = None  # latest boot time seen in this boot
        self.last_recv_s: Optional[float] = None
        self.first_t_us: Optional[int] = None
        self.unix_offset_us: Optional[int] = None  # unix_us - boot_us from SYSTEM_TIME
        self.duration_us = 0  # completed boots
        self.step_us = 0  # added to this boot's times after steps of the vehicle clock

    def classify(self, t_us: int, recv_s: float, behind_us: int = 300_000) -> int:
        """ACCEPT a boot-time value, or HOLD it as a candidate new time base (behind by
        more than ``behind_us``, or ahead by more than the receive time allows)."""
        last = self.last_t_us
        if last is None:
            return ACCEPT
        if t_us < last - min(behind_us, self.jump_us):
            return HOLD
        if self.last_recv_s is not None:
            allowed = 3e6 * max(0.0, recv_s - self.last_recv_s) + 10e6
            if t_us - last > max(allowed, self.jump_us):
                return HOLD
        return ACCEPT

    def accept(self, t_us: int, recv_s: float) -> None:
        if self.last_t_us is None or t_us > self.last_t_us:
            self.last_t_us = t_us
        if self.first_t_us is None:
            self.first_t_us = t_us
        self.last_recv_s = recv_s

    def jump_to(self, t_us: int, recv_s: float) -> None:
        """Move onto a confirmed forward jump (same boot)."""
        self.last_t_us = t_us
        self.last_recv_s = recv_s

    def new_boot(self, t_us: int, recv_s: float) -> int:
        if self.first_t_us is not None and self.last_t_us is not None:
            self.duration_us += self.last_t_us - self.first_t_us
        self.boot += 1
        self.last_t_us = t_us
        self.first_t_us = t_us
        self.last_recv_s = recv_s
        self.unix_offset_us = None
        self.step_us = 0
        return self.boot

    @property
    def total_duration_us(self) -> int:
        cur = 0
        if self.first_t_us is not None and self.last_t_us is not None:
            cur = self.last_t_us - self.first_t_us
        return self.duration_us + cur

    def set_unix_offset(self, unix_us: int, boot_us: int) -> None:
        if unix_us > UNIX_THRESHOLD_US:
            self.unix_offset_us = unix_us - boot_us

    def boot_from_usec(self, t_us: int, recv_s: float) -> Optional[int]:
        """Boot time from a ``time_usec`` field that may be Unix time (None: cannot place it)."""
        if t_us == 0:
            return self.estimate(recv_s)
        if t_us < UNIX_THRESHOLD_US:
            return t_us
        if self.unix_offset_us is not None:
            return t_us - self.unix_offset_us
        if self.last_t_us is None or self.last_recv_s is None:
            return None
        return t_us - (int(round(self.last_recv_s * 1e6)) - self.last_t_us)

    def estimate(self, recv_s: float) -> Optional[int]:
        """Vehicle time of a message without a time field."""
        if self.last_t_us is None or self.last_recv_s is None:
            return None
        return self.last_t_us + max(0, int(round((recv_s - self.last_recv_s) * 1e6)))


class StreamClocks:
    """Time streams that may not be on the autopilot's boot clock.

    Old ArduPilot stamps RAW_IMU ``time_usec`` from a clock seconds away
    from its ``time_boot_ms``; a sonar component stamps DISTANCE_SENSOR with
    its own boot time; GNSS time may lag. Each such stream (key: component
    and message) is compared, over its first ``n`` samples, with the vehicle
    clock's receive-time estimate; if the median difference exceeds
    ``threshold_s`` the stream runs on its own clock and is shifted by that
    (fixed) median, otherwise it is taken as is. The samples are held while
    this is decided, and the decision is remade after a reboot.
    """

    def __init__(self, n: int = 5, threshold_s: float = 0.5):
        self.n = n
        self.threshold_us = threshold_s * 1e6
        self.offsets = {}  # key -> offset_us (0: same clock)
        self._held = {}  # key -> [(t_raw, est, item)]

    def reset(self) -> None:
        self.offsets.clear()

    def map(self, key, t_raw: int, est: Optional[int], item) -> list:
        """``[(t_us, item), ...]`` ready now (possibly none, possibly several)."""
        off = self.offsets.get(key)
        if off is not None:
            return [(t_raw - off, item)]
        held = self._held.setdefault(key, [])
        held.append((t_raw, est, item))
        if len(held) >= self.n:
            return self._decide(key)
        return []

    def _decide(self, key) -> list:
        held = self._held.pop(key, [])
        diffs = sorted(t - e for t, e, _ in held if e is not None)
        off = 0
        if diffs:
            med = diffs[len(diffs) // 2]
            if abs(med) > self.threshold_us:
                off = med
        self.offsets[key] = off
        return [(t - off, item) for t, _, item in held]

    def flush(self) -> list:
        out = []
        for key in list(self._held):
            out.extend(self._decide(key))
        return out
