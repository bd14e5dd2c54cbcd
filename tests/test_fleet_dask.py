"""The fleet audit on a real Dask cluster gives the single-process audit's results.

A ``distributed.LocalCluster`` with two worker processes audits a directory
of logs (short shared tlogs, sitl_logs, one generated here) plus a corrupt
file: every per-file dict equals :func:`mavnav.audit.audit_file`'s (less the
``fleet`` entry, which holds timing and worker names), and the corrupt file
is reported with its error while the others are audited.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import distributed
import pytest
from click.testing import CliRunner

from mavnav.audit import audit_file
from mavnav.cli import main
from mavnav.config import load_config
from mavnav.errors import MavnavError
from mavnav.fleet import audit_parallel, run_fleet
from mavnav.ingest import expand_tlog_paths
from tests.support.paths import REPO, SHARED_TLOGS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SHARED = SHARED_TLOGS
SHORT_SHARED = ["real/gridlines_copter_indoor_nofix.tlog", "other/copter_sitl_mixed_v1_v2.tlog"]
# (the second raises an alarm: --fail-on has something to decide on)
SITL = ["ardupilot_rng_dropout.tlog", "px4_hover_gnss_step.tlog"]


def _json(x):
    return json.loads(json.dumps(x, default=str))


def _core(r: dict) -> dict:
    return {k: v for k, v in r.items() if k != "fleet"}


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fleet")
    (d / "sitl").mkdir()
    (d / "shared").mkdir()
    for name in SITL:
        shutil.copy(REPO / "sitl_logs" / name, d / "sitl" / name)
    for rel in SHORT_SHARED:
        if (SHARED / rel).is_file():
            shutil.copy(SHARED / rel, d / "shared" / Path(rel).name)
    r = CliRunner().invoke(main, ["simulate", str(REPO / "config/scenarios/ardupilot_rng_dropout.yaml"),
                                  "-o", str(d / "sitl" / "generated_seed7.tlog"), "--seed", "7"])
    assert r.exit_code == 0, r.output
    (d / "corrupt.tlog").write_bytes(bytes(range(256)) * 40)
    return d


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as c:
        yield c


@pytest.mark.realdata
def test_dask_cluster_matches_single_process(fleet_dir, cluster, tmp_path):
    files = expand_tlog_paths(fleet_dir)
    assert len(files) >= 4
    cfg = load_config(None)
    run = run_fleet(files, cfg, scheduler=cluster.scheduler_address, cache_dir=tmp_path / "cache")
    assert run.backend == "dask"
    assert [r["path"] for r in run.results] == [str(f) for f in files]  # input order

    bad = [r for r in run.results if "error" in r]
    assert [Path(r["path"]).name for r in bad] == ["corrupt.tlog"]
    assert "not a tlog" in bad[0]["error"]
    assert run.counts.failed == 1 and run.counts.done == len(files) - 1 and run.counts.skipped == 0

    for f, r in zip(files, run.results):
        if f.name == "corrupt.tlog":
            with pytest.raises(MavnavError):
                audit_file(f, cfg)
            continue
        expected = _json(audit_file(f, cfg))
        assert _core(r) == expected, f
        assert r["fleet"]["cached"] is False and len(r["fleet"]["sha256"]) == 64
    # The tasks ran in the workers, not here.
    import os
    assert all(not r["fleet"]["worker"].endswith(f":{os.getpid()}") for r in run.results)


def test_audit_parallel_entry_and_cli_exit_codes(fleet_dir, cluster, tmp_path):
    good = [fleet_dir / "sitl" / n for n in SITL]
    # The CLI's entry point: a list of dicts in input order, no cache unless asked.
    res = audit_parallel(good + [fleet_dir / "corrupt.tlog"], scheduler=cluster.scheduler_address)
    assert [Path(r["path"]).name for r in res] == SITL + ["corrupt.tlog"]
    assert "error" in res[-1] and all("error" not in r for r in res[:-1])

    runner = CliRunner()
    args = ["audit", *map(str, good), "--scheduler", cluster.scheduler_address, "--cache-dir", str(tmp_path / "c")]
    r = runner.invoke(main, args)
    assert r.exit_code == 0, r.output
    r = runner.invoke(main, args + ["--fail-on", "caution"])  # px4_hover_gnss_step has an alarm
    assert r.exit_code == 1, r.output
    r = runner.invoke(main, args + [str(fleet_dir / "corrupt.tlog"), "--json", str(tmp_path / "a.json")])
    assert r.exit_code == 2, r.output
    doc = json.loads((tmp_path / "a.json").read_text())
    assert sorted(Path(f["path"]).name for f in doc["files"]) == sorted(SITL + ["corrupt.tlog"])
    assert [f["path"] for f in doc["files"] if "error" in f] == [str(fleet_dir / "corrupt.tlog")]


def test_unreachable_scheduler_is_a_one_line_error(tmp_path, monkeypatch):
    import socket

    import mavnav.fleet.runner

    monkeypatch.setattr(mavnav.fleet.runner, "SCHEDULER_TIMEOUT", "1s")
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    r = CliRunner().invoke(main, ["audit", str(REPO / "sitl_logs" / SITL[0]), "--scheduler",
                                  f"tcp://127.0.0.1:{port}", "--no-cache"])
    assert r.exit_code != 0
    assert isinstance(r.exception, SystemExit) and r.exit_code == 2  # a user error, not a traceback
    assert r.output.startswith(f"mavnav: error: cannot reach the Dask scheduler at tcp://127.0.0.1:{port}")
    assert r.output.count("\n") == 1
