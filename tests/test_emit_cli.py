"""The ``--emit`` options and the sink factory, through click's runner."""

from __future__ import annotations

import hashlib

import click
import pytest
from click.testing import CliRunner

from mavnav.cli.emit_options import emit_options, emit_sinks, make_emit_sinks
from mavnav.config import Config
from mavnav.errors import ConfigError
from mavnav.report import RunSummary
from mavnav.sinks.mavlink_out import MavlinkOutSink
from tests.support.emit import Peer, feed, reports_every

pytestmark = [pytest.mark.integration]


def _command(store: dict, **factory_kw):
    @click.command()
    @click.option("--other", default="x")
    @emit_options
    def cmd(other, emit_flags):
        store["rest"] = {"other": other}
        store["emit"] = emit_flags
        store["sinks"] = emit_sinks(Config(), emit_flags, **factory_kw)

    return cmd


def invoke(args, **factory_kw):
    store = {}
    res = CliRunner().invoke(_command(store, **factory_kw), args, catch_exceptions=True)
    return res, store


def test_options_are_listed_in_help():
    res, _ = invoke(["--help"])
    assert res.exit_code == 0
    for opt in ("--emit", "--emit-sysid", "--emit-compid", "--altitude-rate", "--statustext-interval", "--emit-debug",
                "--emit-fusable", "--allow-commands", "--request-rate", "--signing-key", "--signing-link-id"):
        assert opt in res.output


def test_no_emit_no_sink():
    res, store = invoke([])
    assert res.exit_code == 0, res.output
    assert store["emit"] == {}  # only the flags given reach the command
    assert store["sinks"] == [] and store["rest"] == {"other": "x"}


@pytest.mark.parametrize("flag", [["--allow-commands"], ["--emit-debug"], ["--emit-fusable"],
                                  ["--request-rate", "ATTITUDE:10"]])
def test_emit_flags_without_emit_are_refused(flag):
    res, _ = invoke(flag)
    assert isinstance(res.exception, ConfigError) and "without --emit" in str(res.exception)


def test_signing_key_without_emit_is_refused(tmp_path):
    (tmp_path / "k").write_text("pass\n")
    res, _ = invoke(["--signing-key", str(tmp_path / "k")])
    assert isinstance(res.exception, ConfigError) and "--signing-key" in str(res.exception)


def test_request_rate_needs_allow_commands():
    res, _ = invoke(["--emit", "udpout:127.0.0.1:9", "--request-rate", "ATTITUDE:10"])
    assert isinstance(res.exception, ConfigError) and "--allow-commands" in str(res.exception)


@pytest.mark.parametrize("args,match", [
    (["--emit-compid", "1"], "2<=x<=255"),
    (["--emit-sysid", "0"], "1<=x<=255"),
    (["--altitude-rate", "0"], "0<x<=100"),
])
def test_bad_values_are_refused_by_click(args, match):
    res, _ = invoke(["--emit", "udpout:127.0.0.1:9"] + args)
    assert res.exit_code == 2 and match in res.output


def test_emit_input_needs_a_live_run():
    res, _ = invoke(["--emit", "input"], live_input=False)
    assert isinstance(res.exception, ConfigError) and "live input link" in str(res.exception)
    res, store = invoke(["--emit", "input"], live_input=True)
    assert res.exit_code == 0 and isinstance(store["sinks"][0], MavlinkOutSink)
    assert store["sinks"][0].use_input_link


def test_misspelt_factory_keyword_is_an_error():
    with pytest.raises(TypeError, match="unexpected keyword argument 'altitude_rate_hz'"):
        make_emit_sinks(emit=None, altitude_rate_hz=5.0)


def test_unopenable_connection_is_a_user_error():
    from mavnav.errors import InputError

    with pytest.raises(InputError, match="cannot open"):
        make_emit_sinks(emit="tcp:127.0.0.1:1")  # nothing listens on port 1


def test_options_reach_the_wire(tmp_path):
    (tmp_path / "key").write_text("ground station passphrase\n")
    key = hashlib.sha256(b"ground station passphrase").digest()
    peer = Peer(key=key)
    try:
        res, store = invoke(["--emit", peer.url, "--emit-sysid", "7", "--emit-compid", "192",
                             "--altitude-rate", "10", "--emit-debug", "--emit-fusable",
                             "--signing-key", str(tmp_path / "key"), "--signing-link-id", "3",
                             "--allow-commands", "--request-rate", "attitude:25"])
        assert res.exit_code == 0, res.output
        (sink,) = store["sinks"]
        cfg = sink.settings
        assert (cfg.sysid, cfg.compid, cfg.altitude_rate_hz, cfg.debug_values, cfg.fusable) == (7, 192, 10.0, True, True)
        assert [(r.name, r.rate_hz) for r in sink.message_rates] == [("ATTITUDE", 25.0)]
        assert sink.allow_commands and sink.requester is not None
        sink.start({})
        feed(sink, reports_every(0.02, 1.0))
        sink.close(RunSummary())
        assert peer.wait_for(lambda: len(peer.of("ALTITUDE")) == 10 and len(peer.of("ODOMETRY")) == 10)
        assert not peer.bad and all(m._signed and m._link_id == 3 for m in peer.msgs)
        assert {(m.get_srcSystem(), m.get_srcComponent()) for m in peer.msgs} == {(7, 192)}
        assert len(peer.of("NAMED_VALUE_FLOAT")) == 10 * 11
    finally:
        peer.close()
