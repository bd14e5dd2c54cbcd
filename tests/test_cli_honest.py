"""Honest exits: ``--sysid`` naming no vehicle in the log is an error listing the
vehicles seen (never "0 epochs", exit 0, and a passing ``--fail-on``); every
output path is checked before any work (one line, exit 2, no traceback); a tlog
cut mid-record says where."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from mavnav.cli import main
from tests.support.flightlog import FlightLog
from tests.support.paths import REPO

pytestmark = [pytest.mark.integration]

SCENARIO = REPO / "config" / "scenarios" / "px4_hover_gnss_step.yaml"


@pytest.fixture(scope="module")
def two_systems(tmp_path_factory):
    """A short flight of vehicle 1 (PX4 quadrotor) with a ground station (sysid 255) on the link."""
    f = FlightLog(tmp_path_factory.mktemp("honest") / "two.tlog")
    f.fly(0, 4, height_fn=lambda t: t)
    for t in (0.5, 1.5, 2.5):
        f.heartbeat(t, mav_type=6, autopilot=8, sysid=255, compid=190)
    return f.close()


def _invoke(args):
    res = CliRunner().invoke(main, [str(a) for a in args])
    # a user error is a SystemExit with a status, never an escaped exception
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    return res


def _one_error_line(res):
    """The one line saying what is wrong (ours, or click's own usage error for a path
    its type already refuses, e.g. a directory given for a file)."""
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith(("mavnav: error:", "Error:"))]
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.output
    return lines[0]


def test_replay_with_an_absent_sysid_is_an_error_naming_the_vehicles_seen(two_systems):
    res = _invoke(["replay", two_systems, "--sysid", "7"])
    assert res.exit_code == 2
    line = _one_error_line(res)
    assert "no data from --sysid 7" in line
    assert "sysid 1 (PX4 quadrotor, 4 heartbeats)" in line and "sysid 255 (gcs, 3 heartbeats)" in line
    assert _invoke(["replay", two_systems, "--sysid", "1"]).exit_code == 0


def test_audit_with_an_absent_sysid_fails_even_with_fail_on(two_systems, tmp_path):
    js = tmp_path / "a.json"
    res = _invoke(["audit", two_systems, "--sysid", "7", "--fail-on", "alarm", "--json", js])
    assert res.exit_code == 2
    doc = json.loads(js.read_text())
    err = doc["files"][0]["error"]
    assert "no data from --sysid 7" in err and "sysid 1 (PX4 quadrotor, 4 heartbeats)" in err
    assert "0 epochs" not in res.output
    ok = _invoke(["audit", two_systems, "--sysid", "1", "--fail-on", "alarm"])
    assert ok.exit_code == 0, ok.output


def _bad_outputs(tmp_path):
    """Paths no file can be written to, whoever runs the test (root included)."""
    a_file = tmp_path / "plain.txt"
    a_file.write_text("x")
    a_dir = tmp_path / "adir"
    a_dir.mkdir(exist_ok=True)
    return {
        "parent is a file": a_file / "out.x",
        "no such directory": tmp_path / "missing" / "out.x",
        "is a directory": a_dir,
    }


@pytest.mark.parametrize("case", ["parent is a file", "no such directory", "is a directory"])
@pytest.mark.parametrize("cmd", [
    "replay --csv", "replay --rrd", "audit --csv", "audit --rrd", "audit --json",
    "simulate -o", "simulate --truth", "inject -o",
])
def test_unwritable_output_is_refused_before_any_work(tmp_path, two_systems, cmd, case):
    bad = _bad_outputs(tmp_path)[case]
    verb, opt = cmd.split()
    good_tlog = tmp_path / "good.tlog"
    if verb == "replay":
        args = ["replay", two_systems, opt, bad]
    elif verb == "audit":
        args = ["audit", two_systems, opt, bad]
    elif verb == "simulate":
        args = ["simulate", SCENARIO, "-o", bad if opt == "-o" else good_tlog] + (["--truth", bad] if opt == "--truth" else [])
    else:
        args = ["inject", two_systems, "-o", bad, "gnss_step:onset=1,duration=1,magnitude=10"]
    res = _invoke(args)
    assert res.exit_code == 2, res.output
    line = _one_error_line(res)
    assert str(bad) in line
    # refused before the work: no table, no summary, nothing written
    assert "epochs" not in res.output and "records" not in res.output
    assert not good_tlog.exists()


def test_unwritable_fleet_report_is_refused_before_the_audit(tmp_path, two_systems):
    bad = _bad_outputs(tmp_path)["parent is a file"]
    res = _invoke(["audit", two_systems, "--fleet-report", bad, "--no-cache"])
    assert res.exit_code == 2
    assert str(bad) in _one_error_line(res) and "epochs" not in res.output


def test_truncated_tlog_is_audited_with_a_note_saying_where(tmp_path, two_systems):
    data = two_systems.read_bytes()
    cut = tmp_path / "cut.tlog"
    cut.write_bytes(data[:-7])
    # where the last record starts: walk the records
    pos, last = 0, 0
    while pos < len(data):
        last = pos
        stx, plen = data[pos + 8], data[pos + 9]
        pos += 8 + ((6 + plen + 2) if stx == 0xFE else (10 + plen + 2))
    js = tmp_path / "cut.json"
    res = _invoke(["audit", cut, "--json", js])
    assert res.exit_code == 0, res.output
    notes = json.loads(js.read_text())["files"][0]["notes"]
    want = f"ends mid-record at byte {last}"
    assert any(n.startswith(want) for n in notes), notes
    assert want in res.output
    full = _invoke(["audit", two_systems, "--json", js])
    assert not any("mid-record" in n for n in json.loads(js.read_text())["files"][0]["notes"])


def test_help_and_readme_say_what_each_state_means_and_what_to_do():
    res = CliRunner().invoke(main, ["--help"])
    assert res.exit_code == 0
    lines = res.output.splitlines()
    for state, action in [("nominal", "Nothing to do"), ("caution", "watch the named source"),
                          ("unavailable", "Do not rely on the"), ("alarm", "stop height-critical")]:
        i = next(k for k, ln in enumerate(lines) if ln.strip().startswith(state + " "))
        block = " ".join(ln.strip() for ln in lines[i:i + 5])
        assert action in block, (state, block)
    readme = (REPO / "README.md").read_text()
    section = readme.split("### What the states mean, and what to do")[1].split("\n### ")[0]
    rows = [ln for ln in section.splitlines() if ln.startswith("| `")]
    assert [r.split("`")[1] for r in rows] == ["nominal", "caution", "unavailable", "alarm"]
    assert all(len(r.split("|")) == 5 and len(r.split("|")[3].strip()) > 5 for r in rows)  # each says what to do
