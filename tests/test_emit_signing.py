"""MAVLink 2 signing of mavnav's output: key files, and peers that check signatures."""

from __future__ import annotations

import hashlib
import os

import pytest

from mavnav.errors import ConfigError
from mavnav.report import RunSummary
from mavnav.sinks.mavlink_link import load_signing_key, passphrase_to_key
from tests.support.emit import Peer, event, feed, reports_every, udp_sink

pytestmark = [pytest.mark.integration]

KEY = hashlib.sha256(b"mavnav test key").digest()


def test_raw_32_byte_key_file(tmp_path):
    raw = bytes(range(200, 232))
    (tmp_path / "k").write_bytes(raw)
    assert load_signing_key(tmp_path / "k") == raw


def test_passphrase_file_is_hashed_as_mavproxy_does(tmp_path):
    from MAVProxy.modules.mavproxy_signing import SigningModule

    (tmp_path / "k").write_text("correct horse battery\n")
    mavproxy_key = SigningModule.passphrase_to_key(None, "correct horse battery")
    assert load_signing_key(tmp_path / "k") == mavproxy_key == passphrase_to_key("correct horse battery")


def test_a_32_character_passphrase_is_not_taken_for_a_raw_key(tmp_path):
    text = "a" * 31 + "\n"  # 32 bytes of text
    (tmp_path / "k").write_text(text)
    assert load_signing_key(tmp_path / "k") == hashlib.sha256(b"a" * 31).digest()


@pytest.mark.parametrize("content,match", [(b"", "empty"), (b"\n \n", "empty"), (b"\xff\xfe\x00" * 5, "binary")])
def test_wrong_key_files_are_refused_by_name(tmp_path, content, match):
    (tmp_path / "k").write_bytes(content)
    with pytest.raises(ConfigError, match=match):
        load_signing_key(tmp_path / "k")
    with pytest.raises(ConfigError, match="cannot read"):
        load_signing_key(tmp_path / "missing")


def _emit_signed(peers, key=KEY, link_id=7):
    for p in peers:
        sink = udp_sink(p, signing_secret=key, signing_link_id=link_id)
        sink.start({})
        feed(sink, reports_every(0.02, 1.0))
        sink.alarm(event(1.0))
        sink.close(RunSummary())


def test_signed_output_is_accepted_with_the_key_and_rejected_with_another():
    good = Peer(key=KEY)
    wrong = Peer(key=hashlib.sha256(b"another key").digest())
    plain = Peer()
    try:
        _emit_signed([good, wrong, plain])
        # 1 + 1 HEARTBEAT, 5 ALTITUDE, 1 STATUSTEXT
        assert good.wait_for(lambda: len(good.msgs) == 8)
        assert wrong.wait_for(lambda: len(wrong.bad) == 8)
        assert plain.wait_for(lambda: len(plain.msgs) == 8)
        assert not good.bad and not wrong.msgs
        assert all(m._signed and m._link_id == 7 for m in good.msgs)
        assert {m.get_type() for m in good.msgs} == {"HEARTBEAT", "ALTITUDE", "STATUSTEXT"}
        assert good.mav.signing.goodsig_count == 8 and good.mav.signing.badsig_count == 0
        assert wrong.mav.signing.badsig_count == 8
        assert all("signature" in b.reason.lower() for b in wrong.bad)
        # a peer that does not check signatures still reads the frames (signing authenticates)
        assert all(m.get_msgbuf()[2] & 0x01 for m in plain.msgs)  # MAVLINK_IFLAG_SIGNED
    finally:
        for p in (good, wrong, plain):
            p.close()


def test_unsigned_output_is_rejected_by_a_peer_that_requires_signatures():
    strict = Peer(key=KEY)
    try:
        sink = udp_sink(strict)
        sink.start({})
        feed(sink, reports_every(0.02, 0.4))
        assert strict.wait_for(lambda: len(strict.bad) == 1 + 1 + 2)
        assert not strict.msgs and strict.mav.signing.reject_count == 4
    finally:
        strict.close()


def test_signing_timestamps_increase_from_the_wall_clock():
    p = Peer(key=KEY)
    try:
        _emit_signed([p])
        assert p.wait_for(lambda: len(p.msgs) == 8)
        ts = [int.from_bytes(m.get_msgbuf()[-12:-6], "little") for m in p.msgs]
        assert ts == sorted(ts) and len(set(ts)) == len(ts)
        import time

        now = int((time.time() - 1420070400) * 100_000)
        assert abs(ts[0] - now) < 60 * 100_000  # within a minute of now, in 10 us units
    finally:
        p.close()


def test_key_of_wrong_length_is_refused():
    from mavnav.sinks.mavlink_out import MavlinkOutSink

    with pytest.raises(ConfigError, match="32 bytes"):
        MavlinkOutSink(None, signing_secret=os.urandom(16), use_input_link=True)
