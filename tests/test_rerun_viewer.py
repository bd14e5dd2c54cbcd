"""Viewer options and the viewer's lifecycle: a viewer that goes away
changes nothing in the monitor's results; web mode serves on 127.0.0.1;
options parse; the CLI's replay saves an .rrd that equals its CSV."""

from __future__ import annotations

import logging
import math
import urllib.request
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mavnav import pipeline
from tests.support import synthetic
from mavnav.cli.viewer_options import (
    ViewerProcess,
    free_port,
    grpc_url,
    make_viewer_sinks,
    rerun_executable,
    viewer_options,
    viewer_settings,
    viewer_sinks,
    web_page_url,
)
from mavnav.config import Config
from mavnav.errors import MavnavError
from mavnav.sinks.base import Sink
from mavnav.sinks.csv_sink import CsvSink

from tests.support.rerun import read_rrd
from tests.support.paths import REPO

pytestmark = [pytest.mark.integration]

LOG_WITH_REBOOT = REPO / "sitl_logs" / "ardupilot_input_faults.tlog"


@pytest.fixture(scope="module")
def flight():
    return synthetic.paper_flight(seed=5, schedule=synthetic.Schedule(duration_s=20.0))


@pytest.fixture
def grpc_server():
    """A Rerun gRPC server of our own, on 127.0.0.1, to connect to and to stop."""
    port = free_port()
    proc = ViewerProcess([rerun_executable(), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)],
                         "127.0.0.1", (port,))
    assert proc.wait_ready() is None, proc.tail()
    yield proc, port
    proc.stop()


class Capture(Sink):
    name = "capture"

    def __init__(self):
        self.rows = []

    def epoch(self, r):
        self.rows.append(repr(r))  # repr: NaN compares equal as text


class StopAfter(Sink):
    """Stops the viewer's server after n epochs: the viewer goes away mid-run."""

    name = "stopper"

    def __init__(self, n, proc):
        self.n, self.proc, self.seen = n, proc, 0

    def epoch(self, r):
        self.seen += 1
        if self.seen == self.n:
            self.proc.stop()


def _run(flight, tmp_path, name, extra=()):
    capture = Capture()
    csv_path = tmp_path / f"{name}.csv"
    summary = pipeline.run(flight.samples, Config(), [capture, CsvSink(csv_path), *extra], info={"source": name})
    return summary, capture.rows, csv_path.read_text()


def _warnings(caplog):
    return [r for r in caplog.records if r.name == "mavnav.sinks.rerun" and r.levelno >= logging.WARNING]


# --------------------------------------------------------------------------
# A viewer that goes away


@pytest.mark.slow
@pytest.mark.parametrize("live", [True, False], ids=["live-rows", "replay-columns"])
def test_viewer_dropped_mid_run_changes_nothing_and_is_reported_once(flight, tmp_path, grpc_server, caplog, live):
    proc, port = grpc_server
    base_summary, base_rows, base_csv = _run(flight, tmp_path, "base")

    [sink] = make_viewer_sinks("none", f"rerun+http://127.0.0.1:{port}/proxy", None, live=live)
    sink.check_interval_s = 0.0  # look at the viewer at every epoch
    caplog.set_level(logging.WARNING, logger="mavnav.sinks.rerun")
    summary, rows, csv_text = _run(flight, tmp_path, "viewer", [StopAfter(300, proc), sink])

    assert proc.proc.poll() is not None  # the server really went away mid-run
    assert summary.sink_failures == {}  # not dropped: it caught and reported
    assert (summary.epochs, summary.alarms, summary.reboots) == (base_summary.epochs, base_summary.alarms,
                                                                base_summary.reboots)
    assert rows == base_rows and csv_text == base_csv
    warnings = _warnings(caplog)
    assert len(warnings) == 1 and "is gone" in warnings[0].getMessage()
    assert sink.lost and not sink.enabled  # nothing left to write to: logging stopped


@pytest.mark.slow
def test_viewer_lost_but_rrd_still_written(flight, tmp_path, grpc_server, caplog):
    proc, port = grpc_server
    rrd = tmp_path / "kept.rrd"
    [sink] = make_viewer_sinks("none", str(port), str(rrd), live=True)
    sink.check_interval_s = 0.0
    caplog.set_level(logging.WARNING, logger="mavnav.sinks.rerun")
    summary, rows, _ = _run(flight, tmp_path, "kept", [StopAfter(100, proc), sink])
    assert len(_warnings(caplog)) == 1 and ".rrd file is still written" in _warnings(caplog)[0].getMessage()
    rec = read_rrd(rrd)
    assert len(rec.scalars["heights/fused"]) == summary.epochs == len(rows)


@pytest.mark.slow
def test_no_viewer_at_the_url_is_reported_and_the_run_goes_on(flight, tmp_path):
    said = []
    rrd = tmp_path / "alone.rrd"
    sinks = make_viewer_sinks("none", f"127.0.0.1:{free_port()}", str(rrd), live=True, echo=said.append)
    assert len(said) == 1 and "no Rerun viewer listens" in said[0]
    [sink] = sinks
    assert sink.targets == [] and sink.has_file  # the .rrd is still written
    summary, rows, _ = _run(flight, tmp_path, "alone", sinks)
    assert summary.sink_failures == {} and len(read_rrd(rrd).scalars["heights/fused"]) == len(rows)


def test_spawn_without_a_display_warns_and_goes_on(tmp_path, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    said = []
    sinks = make_viewer_sinks("spawn", None, str(tmp_path / "s.rrd"), live=True, grpc_port=free_port(),
                              echo=said.append)
    assert len(said) == 1 and "could not start" in said[0]
    assert len(sinks) == 1 and sinks[0].targets == []  # the .rrd is still written
    sinks[0].close(None)
    assert (tmp_path / "s.rrd").stat().st_size > 0


# --------------------------------------------------------------------------
# Web mode


def _listen_addresses(port: int) -> set[str]:
    """Local addresses listening on a TCP port (from /proc/net/tcp, tcp6)."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            addr, hexport = local.split(":")
            if state == "0A" and int(hexport, 16) == port:
                found.add(addr)
    return found


def test_web_mode_serves_page_and_data_on_localhost_and_prints_the_url():
    said = []
    [sink] = make_viewer_sinks("web", None, None, live=True, web_port=0, grpc_port=0, viewer_hold=False,
                               echo=said.append)
    try:
        assert said == [f"mavnav: Rerun web viewer at {sink.page_url}"]
        [proc] = sink.processes
        grpc_port, web_port = proc.ports
        assert sink.page_url.startswith(f"http://127.0.0.1:{web_port}/?renderer=webgl&url=rerun%2Bhttp")
        assert _listen_addresses(grpc_port) == {"0100007F"}  # 127.0.0.1 only
        assert _listen_addresses(web_port) == {"0100007F"}
        page = urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=10).read().decode()
        assert "re_viewer.js" in page
    finally:
        for p in sink.processes:
            p.stop()
    assert sink.processes[0].proc.poll() is not None


# --------------------------------------------------------------------------
# Options


def test_connect_urls():
    assert grpc_url("9877") == ("rerun+http://127.0.0.1:9877/proxy", "127.0.0.1", 9877)
    assert grpc_url("viewer.local:1234") == ("rerun+http://viewer.local:1234/proxy", "viewer.local", 1234)
    assert grpc_url("rerun+https://example.org/proxy")[2] == 443
    assert grpc_url("rerun://10.0.0.2/proxy")[1:] == ("10.0.0.2", 9876)
    for bad in ("http://127.0.0.1:9876/proxy", "rerun+http://127.0.0.1:9876/", "rerun+http://h:99999/proxy"):
        with pytest.raises(MavnavError, match="--connect '.*': (expected rerun|bad port)"):
            grpc_url(bad)
    assert web_page_url("0.0.0.0", 9090, "rerun+http://127.0.0.1:9876/proxy") == (
        "http://127.0.0.1:9090/?renderer=webgl&url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy")


def test_viewer_options_decorator_parses_and_feeds_the_factory(tmp_path):
    got = {}

    @click.command()
    @viewer_options
    def cmd(viewer_flags):
        got["flags"] = viewer_flags
        got["viewer"] = v = viewer_settings(Config(), viewer_flags)
        got["sinks"] = viewer_sinks(v, live=False)

    runner = CliRunner()
    res = runner.invoke(cmd, [])
    assert res.exit_code == 0, res.output
    v = got["viewer"]
    assert got["flags"] == {}  # only the flags given reach the command
    assert v.viewer == "none" and v.connect is None and v.rrd is None
    assert v.web_port == 9090 and v.grpc_port == 9876 and v.bind == "127.0.0.1"
    assert v.hold is True and v.window_s == 30.0
    assert got["sinks"] == []

    rrd = tmp_path / "o.rrd"
    res = runner.invoke(cmd, ["--rrd", str(rrd), "--viewer-window", "12", "--no-viewer-hold"])
    assert res.exit_code == 0, res.output
    [sink] = got["sinks"]
    assert sink.window_s == 12.0 and not sink.live and sink.has_file
    sink.close(None)

    res = runner.invoke(cmd, ["--viewer", "native"])
    assert res.exit_code == 2 and "native" in res.output
    with pytest.raises(MavnavError, match="expected rerun\\+http://HOST:PORT/proxy or a port"):
        make_viewer_sinks("none", "http://nowhere/proxy", None, live=False)


# --------------------------------------------------------------------------
# The CLI's replay: the .rrd holds what the CSV says


def _ok_flags(states: list, times: list) -> list:
    """The state lane at each time (lanes hold changes only)."""
    out, i, cur = [], 0, None
    for t in times:
        while i < len(states) and states[i][0] <= t:
            cur = states[i][1]
            i += 1
        out.append(cur)
    return out


def test_cli_replay_rrd_equals_its_csv(tmp_path):
    import mavnav.cli.run  # noqa: F401  (registers run and replay)
    from mavnav.cli import main

    csv_path, rrd = tmp_path / "r.csv", tmp_path / "r.rrd"
    res = CliRunner().invoke(main, ["replay", str(LOG_WITH_REBOOT), "--csv", str(csv_path), "--rrd", str(rrd)])
    assert res.exit_code == 0, res.output
    lines = csv_path.read_text().splitlines()
    header, rows = lines[0].split(","), [dict(zip(lines[0].split(","), ln.split(","))) for ln in lines[1:]]
    rows = [r for r in rows if not r["event"]]  # the epochs (event rows: reboot, link lost / recovered)
    rec = read_rrd(rrd)
    fused = rec.scalars["heights/fused"]
    assert len(fused) == len(rows) > 100

    def close(a: float, b: str) -> bool:
        return (math.isnan(a) and b == "nan") or abs(a - float(b)) <= 0.6e-4

    # the reboot: vehicle time restarts in the CSV, the viewer's axis continues with one offset per boot
    reboot = [x for _, x, _ in rec.texts["input/events"] if x.startswith("reboot")]
    assert len(reboot) == 1
    offsets = sorted({round(t * 1e-9 - float(r["t_s"]), 6) for (t, _), r in zip(fused, rows)})
    assert len(offsets) == 2 and offsets[0] == 0.0
    times = [t for t, _ in fused]
    for col, entity in (("height_fused_m", "heights/fused"), ("height_gnss_ch_m", "heights/channel/gnss"),
                        ("height_rng_ch_m", "heights/channel/rangefinder"),
                        ("height_baro_ch_m", "heights/channel/baro")):
        got = rec.scalars[entity]
        assert [t for t, _ in got] == times
        assert all(close(v[0], r[col]) for (_, v), r in zip(got, rows)), col
    sig = [(v[1] - v[0]) / 2 for _, v in rec.scalars["heights/fused_sigma"]]
    assert all(close(s, r["sigma_fused_m"]) for s, r in zip(sig, rows))
    for col, lane in (("gnss_ok", "gnss"), ("rng_ok", "rangefinder"), ("baro_ok", "baro_ins")):
        states = _ok_flags(rec.states[f"state/source/{lane}"], times)
        assert [("1" if s in ("nominal", "caution") else "0") for s in states] == [r[col] for r in rows], col
    assert _ok_flags(rec.states["state/overall"], times) == [r["alarm"] for r in rows]
    assert "alarm" in header
