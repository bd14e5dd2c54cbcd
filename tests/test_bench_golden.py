"""``bench/golden.py``: the MAVLink capture of a replay (through a pseudo-terminal)
and ``compare``, which says where two captures first differ."""

from __future__ import annotations

from collections import Counter

import pytest

from bench.golden import _END, compare, first_mavlink_difference, mavlink_capture
from tests.support.paths import SITL_LOGS

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    return mavlink_capture(SITL_LOGS / "ardupilot_rng_dropout.tlog", tmp_path_factory.mktemp("golden"))


@pytest.mark.slow
def test_the_capture_holds_every_frame_the_replay_sent(capture):
    from bench.golden import _frames

    data, rc, _ = capture
    assert rc == 0
    frames = _frames(data)
    kinds = Counter(f.get_type() for f in frames)
    assert "BAD_DATA" not in kinds
    assert {"HEARTBEAT", "ALTITUDE", "STATUSTEXT", "NAMED_VALUE_FLOAT", "ODOMETRY"} <= set(kinds)
    assert b"".join(f.get_msgbuf() for f in frames) == data  # nothing between or after the frames
    assert _END not in data
    seqs = [f.get_seq() for f in frames]
    assert seqs[0] == 0 and all((b - a) % 256 == 1 for a, b in zip(seqs, seqs[1:]))  # none dropped
    assert {(f.get_srcSystem(), f.get_srcComponent()) for f in frames} == {(1, 191)}


@pytest.mark.slow
def test_compare_says_the_first_differing_frame(capture, tmp_path, capsys):
    data = capture[0]
    n = len(data) // 2
    before, after = tmp_path / "before", tmp_path / "after"
    before.mkdir()
    after.mkdir()
    (before / "x.mavlink").write_bytes(data)
    (after / "x.mavlink").write_bytes(data)
    assert compare(before, after) == 0
    (after / "x.mavlink").write_bytes(data[:n] + bytes([data[n] ^ 0x01]) + data[n + 1:])
    assert compare(before, after) == 1
    out = capsys.readouterr().out
    assert "DIFFERS: x.mavlink" in out and "first: frame " in out
    assert " frames != " in first_mavlink_difference(data, data[:n])  # a cut capture: fewer frames
