"""The reboot rule, written once (mavnav.ingest.clock.is_reboot): the normaliser's
vehicle clock and the fault injector count the same boots."""

from __future__ import annotations

import pytest

from mavnav.config import REBOOT_JUMP_S, IngestConfig
from mavnav.ingest import TlogSource
from mavnav.ingest.clock import is_reboot
from mavnav.sim.inject import inject_bytes
from tests.support.tlog_writer import TlogWriter


def test_the_rule():
    assert IngestConfig().reboot_jump_s == REBOOT_JUMP_S == 2.0
    jump_us = int(REBOOT_JUMP_S * 1e6)
    assert is_reboot(30_000_000, 27_999_999, jump_us)
    assert not is_reboot(30_000_000, 28_000_000, jump_us)  # exactly the jump back: a clock step
    assert not is_reboot(1_500_000, 0, jump_us)  # a step back shorter than the jump, even to zero


def _tlog(path, times_s) -> bytes:
    """An ArduPilot heartbeat and ATTITUDE at 10 Hz of receive time, stamped ``times_s``."""
    with TlogWriter(path) as w:
        recv = 1.7e9
        for i, t in enumerate(times_s):
            if i % 10 == 0:
                w.write(w.mav.heartbeat_encode(2, 3, 0, 0, 4, 3), recv)
            w.write(w.mav.attitude_encode(int(round(t * 1000)), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), recv)
            recv += 0.1
    return path.read_bytes()


def _normaliser_reboots(path) -> int:
    src = TlogSource(str(path))
    for _ in src:
        pass
    return src.stats.reboots


@pytest.mark.parametrize("before_s, after_s, boots", [
    (30.0, 27.0, 2),  # 3 s back at 30 s: a reboot (the injector's old rule wanted 10 s here)
    (1.5, 0.1, 1),  # 1.4 s back at 1.5 s: a step of the clock (the old rule: a reboot)
    (60.0, 0.0, 2),  # a restart from zero
])
def test_injector_and_normaliser_count_the_same_boots(tmp_path, before_s, after_s, boots):
    n1, n2 = int(before_s * 10), 50
    times = [k * 0.1 for k in range(n1 + 1)] + [after_s + k * 0.1 for k in range(n2)]
    data = _tlog(tmp_path / "clock.tlog", times)
    _, report = inject_bytes(data, [])
    assert report["boots_seen"] == boots
    assert _normaliser_reboots(tmp_path / "clock.tlog") == boots - 1
