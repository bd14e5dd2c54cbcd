"""The fleet report: Parquet tables read back with pyarrow, the Markdown report and its PNG plots."""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from mavnav.cli import main
from mavnav.config import load_config
from mavnav.fleet import run_fleet
from mavnav.fleet.report import alarm_kind, write_fleet_report
from mavnav.report import SOURCES
from tests.support.paths import REPO

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SITL = ["ardupilot_rng_dropout.tlog", "ardupilot_input_faults.tlog", "px4_hover_gnss_step.tlog"]


def test_alarm_kind_groups_reasons_without_their_numbers():
    assert alarm_kind("innovations too large over 5 s (sum 76 > 73) (baro in the GNSS channel)") \
        == alarm_kind("innovations too large over 5 s (sum 104 > 99)") == "innovations too large over # s"
    assert alarm_kind("too slow for 1.0 s alarm: imu 4.2 Hz < 10") == "too slow for # s alarm"
    assert alarm_kind("rng-baro -3.03 m, threshold 2.99 m") == "rng-baro # m"
    assert alarm_kind("4 samples rejected in 5 s (last 7.9 sigma)") == "# samples rejected in # s"
    assert alarm_kind("") == "?"


def test_parquet_tables_and_report(tmp_path):
    files = [REPO / "sitl_logs" / n for n in SITL]
    bad = tmp_path / "bad.tlog"
    bad.write_bytes(b"not a tlog at all" * 100)
    run = run_fleet(files + [bad], load_config(None))
    results = run.results
    out = tmp_path / "report"
    written = write_fleet_report(results, out, run_info={"backend": run.backend})

    t = pq.read_table(out / "files.parquet")
    assert t.num_rows == 4
    cols = set(t.column_names)
    assert {"path", "sha256", "status", "error", "worst_state", "fused_vs_autopilot_max_m", "slow_inputs",
            "time_to_alarm_s"} <= cols
    assert {f"alarms_{s}" for s in SOURCES} <= cols
    assert {f"rate_{k}_hz" for k in ("imu", "baro", "gnss", "rangefinder")} <= cols
    rows = {Path(r["path"]).name: r for r in t.to_pylist()}
    assert rows["bad.tlog"]["status"] == "error" and "not a tlog" in rows["bad.tlog"]["error"]
    for name, r in zip(SITL, results):
        assert rows[name]["status"] == "ok"
        assert rows[name]["fused_vs_autopilot_max_m"] == r["fused_vs_autopilot_max_m"]
        assert rows[name]["alarm_episodes"] == sum(a["state"] == "alarm" for a in r["alarms"])
    assert rows["px4_hover_gnss_step.tlog"]["alarms_gnss"] >= 1  # the +10 m GNSS step

    alarms = pq.read_table(out / "alarms.parquet")
    n_alarms = sum(len(r.get("alarms", [])) for r in results)
    assert alarms.num_rows == n_alarms > 0
    assert alarms.column_names == ["path", "boot", "t_s", "source", "state", "kind", "reason", "cleared_t_s",
                                   "duration_s"]

    summary = pq.read_table(out / "summary.parquet")
    assert {"source", "state", "kind", "episodes", "files"} <= set(summary.column_names)
    assert sum(summary.column("episodes").to_pylist()) == n_alarms

    md = (out / "report.md").read_text()
    for heading in ("## Alarms by source and kind", "## Input rates that cannot support the time-to-alarm",
                    "## Worst disagreement with the autopilot's own height", "## Unreadable files"):
        assert heading in md
    assert "bad.tlog" in md and "4 files" in md
    pngs = [p for p in written.values() if p.suffix == ".png"]
    assert len(pngs) >= 3
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 2000
        assert f"]({p.name})" in md


def test_cli_fleet_report(tmp_path):
    d = tmp_path / "logs"
    d.mkdir()
    for n in SITL[:2]:
        shutil.copy(REPO / "sitl_logs" / n, d / n)
    r = CliRunner().invoke(main, ["audit", str(d), "--fleet-report", str(tmp_path / "rep"),
                                  "--cache-dir", str(tmp_path / "c")])
    assert r.exit_code == 0, r.output
    assert pq.read_table(tmp_path / "rep" / "files.parquet").num_rows == 2
    assert (tmp_path / "rep" / "report.md").is_file()
    assert "fleet report:" in r.stderr
