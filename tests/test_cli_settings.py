"""The ``viewer:`` and ``emit:`` sections of the configuration against their
command-line flags: the key applies when its flag is not given, a flag given wins."""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from mavnav.cli.emit_options import emit_options, emit_settings, emit_sinks
from mavnav.cli.viewer_options import viewer_options, viewer_settings
from mavnav.config import Config, config_from_dict
from mavnav.errors import ConfigError
from mavnav.fleet.task import config_json
from mavnav.report import RunSummary


def _settings(cfg: Config, args: list[str]):
    """The viewer and emit settings a command sees with this configuration and these flags."""
    got = {}

    @click.command()
    @viewer_options
    @emit_options
    def cmd(viewer_flags, emit_flags):
        got["viewer"] = viewer_settings(cfg, viewer_flags)
        got["emit"] = emit_settings(cfg, emit_flags)
        got["emit_flags"] = emit_flags

    res = CliRunner().invoke(cmd, args, catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return got


VIEWER_CFG = config_from_dict({"viewer": {"viewer": "web", "connect": "9877", "web_port": 1234, "grpc_port": 4321,
                                          "bind": "0.0.0.0", "window_s": 5.0, "hold": False}})


def test_viewer_keys_apply_without_flags():
    v = _settings(VIEWER_CFG, [])["viewer"]
    assert (v.viewer, v.connect, v.rrd, v.web_port, v.grpc_port, v.bind, v.window_s, v.hold) == \
        ("web", "9877", None, 1234, 4321, "0.0.0.0", 5.0, False)


def test_viewer_flags_win_over_the_keys():
    v = _settings(VIEWER_CFG, ["--viewer", "none", "--web-port", "2000", "--viewer-bind", "127.0.0.2",
                               "--viewer-window", "60", "--viewer-hold"])["viewer"]
    assert (v.viewer, v.web_port, v.bind, v.window_s, v.hold) == ("none", 2000, "127.0.0.2", 60.0, True)
    assert (v.connect, v.grpc_port) == ("9877", 4321)  # not given: the configuration's


def test_a_flag_at_its_default_value_still_wins():
    # --viewer none is also the built-in default: given, it must override viewer: web
    assert _settings(VIEWER_CFG, ["--viewer", "none"])["viewer"].viewer == "none"
    assert _settings(VIEWER_CFG, ["--web-port", "9090"])["viewer"].web_port == 9090


def test_without_configuration_the_built_in_defaults():
    got = _settings(Config(), [])
    v, e = got["viewer"], got["emit"]
    assert (v.viewer, v.web_port, v.grpc_port, v.bind, v.window_s, v.hold) == ("none", 9090, 9876, "127.0.0.1", 30.0, True)
    assert (e.sysid, e.compid, e.altitude_rate_hz, e.statustext_interval_s) == (1, 191, 5.0, 1.0)
    assert got["emit_flags"] == {}


EMIT_CFG = config_from_dict({"emit": {"sysid": 7, "compid": 192, "altitude_rate_hz": 2.0, "debug_values": True,
                                      "message_rates": ["ATTITUDE:25"]}})


def test_emit_keys_apply_and_flags_win():
    e = _settings(EMIT_CFG, [])["emit"]
    assert (e.sysid, e.compid, e.altitude_rate_hz, e.debug_values) == (7, 192, 2.0, True)
    e = _settings(EMIT_CFG, ["--emit-sysid", "9", "--altitude-rate", "10", "--request-rate", "GPS_RAW_INT:5"])["emit"]
    assert (e.sysid, e.compid, e.altitude_rate_hz) == (9, 192, 10.0)
    assert e.message_rates == ("GPS_RAW_INT:5",)


def test_emit_sink_built_from_the_section_and_the_flags():
    (sink,) = emit_sinks(EMIT_CFG, {"emit": "udpout:127.0.0.1:9", "emit_sysid": 9, "allow_commands": True})
    try:
        c = sink.settings
        assert (c.sysid, c.compid, c.altitude_rate_hz, c.debug_values) == (9, 192, 2.0, True)
        assert sink.config.emit is c and sink.config.monitor is EMIT_CFG.monitor  # the run's, the flags over its emit:
        assert [(r.name, r.rate_hz) for r in sink.message_rates] == [("ATTITUDE", 25.0)]
    finally:
        sink.close(RunSummary())


def test_configured_rates_wait_for_allow_commands():
    # the section's message_rates are a standing choice, used only when commands are allowed
    (sink,) = emit_sinks(EMIT_CFG, {"emit": "udpout:127.0.0.1:9"})
    try:
        assert sink.message_rates is None and not sink.allow_commands and sink.requester is None
    finally:
        sink.close(RunSummary())


def test_only_flags_turn_the_output_on():
    # debug_values in the configuration does not need --emit; the flag does
    assert emit_sinks(EMIT_CFG, {}) == []
    with pytest.raises(ConfigError, match="without --emit"):
        emit_sinks(EMIT_CFG, {"emit_debug": True})
    with pytest.raises(ConfigError, match="unknown key 'emit.connection'"):
        config_from_dict({"emit": {"connection": "udpout:127.0.0.1:9"}})


@pytest.mark.parametrize("data,match", [
    ({"viewer": {"viewer": "tv"}}, "viewer.viewer"),
    ({"viewer": {"web_port": 70000}}, "viewer.web_port"),
    ({"viewer": {"window_s": 0}}, "viewer.window_s"),
    ({"emit": {"compid": 1}}, "emit.compid"),
    ({"emit": {"altitude_rate_hz": 200}}, "emit.altitude_rate_hz"),
])
def test_bad_section_values_are_one_line_errors(data, match):
    with pytest.raises(ConfigError, match=match):
        config_from_dict(data)


def test_output_keys_stay_out_of_the_fleet_cache_key():
    assert config_json(VIEWER_CFG) == config_json(Config()) == config_json(EMIT_CFG)
    assert config_json(config_from_dict({"emit": {"command_attempts": 5}})) != config_json(Config())


def test_audit_takes_the_configured_recording(tmp_path):
    """End to end: viewer.rrd from the configuration makes the audit write a
    recording in its own process, which (as --rrd does) takes exactly one file."""
    from mavnav.cli import main

    missing = str(tmp_path / "none.tlog")  # nothing to audit: the checks are all that runs
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"viewer:\n  rrd: {tmp_path / 'r.rrd'}\n")
    res = CliRunner().invoke(main, ["audit", "--config", str(cfg), missing])
    assert res.exit_code == 2 and "exactly one file" in res.output
    res = CliRunner().invoke(main, ["audit", missing])  # without the key: the missing file is reported
    assert res.exit_code == 2 and "exactly one file" not in res.output and "UNREADABLE" in res.output


@pytest.mark.parametrize("kw,match", [
    ({"compid": 1}, "autopilot"),
    ({"sysid": 0}, "emit.sysid"),
    ({"sysid": 256}, "emit.sysid"),
    ({"altitude_rate_hz": float("nan")}, "altitude_rate_hz"),
    ({"altitude_rate_hz": 0.0}, "altitude_rate_hz"),
    ({"statustext_interval_s": float("inf")}, "statustext_interval_s"),
    ({"statustext_interval_s": -1.0}, "statustext_interval_s"),
    ({"signing_link_id": 256}, "signing_link_id"),
    ({"command_attempts": 0}, "command_attempts"),
    ({"command_timeout_s": 0.0}, "command_timeout_s"),
])
def test_the_emit_section_refuses_bad_values_by_name(kw, match):
    # the sink takes this section (MavlinkOutSink(link, config)): no second set of rules
    with pytest.raises(ConfigError, match=match):
        config_from_dict({"emit": kw})
    config_from_dict({"emit": {}})  # the defaults pass


def test_the_sink_refuses_a_signing_key_of_the_wrong_length():
    from mavnav.sinks.mavlink_out import MavlinkOutSink

    with pytest.raises(ConfigError, match="32 bytes"):
        MavlinkOutSink(None, signing_secret=b"short", use_input_link=True)
