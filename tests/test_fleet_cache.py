"""The fleet result cache: a rerun skips files and returns identical results,
``--rerun`` recomputes, and the key follows the content and the configuration."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from mavnav.cli import main
from mavnav.config import config_from_dict, load_config
from mavnav.fleet import ResultCache, cache_key, config_json, file_sha256, run_fleet
from mavnav.fleet.cache import code_fingerprint
from tests.support.paths import REPO

pytestmark = [pytest.mark.integration, pytest.mark.slow]

# (the second raises an alarm: --fail-on has something to decide on)
SITL = ["ardupilot_rng_dropout.tlog", "px4_hover_gnss_step.tlog"]


def _core(results):
    return [{k: v for k, v in r.items() if k != "fleet"} for r in results]


@pytest.fixture()
def logs(tmp_path) -> list[Path]:
    out = []
    for name in SITL:
        shutil.copy(REPO / "sitl_logs" / name, tmp_path / name)
        out.append(tmp_path / name)
    bad = tmp_path / "zz_corrupt.tlog"
    bad.write_bytes(b"\x00\x01garbage" * 500)
    return out + [bad]


def test_rerun_skips_cached_files_with_identical_results(logs, tmp_path):
    cfg = load_config(None)
    cache = tmp_path / "cache"
    first = run_fleet(logs, cfg, cache_dir=cache)
    assert (first.counts.done, first.counts.failed, first.counts.skipped) == (2, 1, 0)
    assert len(ResultCache(cache)) == 2  # failures are not cached

    second = run_fleet(logs, cfg, cache_dir=cache)
    assert (second.counts.done, second.counts.failed, second.counts.skipped) == (0, 1, 2)
    assert second.backend == "serial"  # only the corrupt file was run again
    assert _core(second.results) == _core(first.results)
    assert [r["fleet"]["cached"] for r in second.results] == [True, True, False]
    assert [r["fleet"]["key"] for r in second.results] == [r["fleet"]["key"] for r in first.results]

    forced = run_fleet(logs, cfg, cache_dir=cache, rerun=True)
    assert (forced.counts.done, forced.counts.failed, forced.counts.skipped) == (2, 1, 0)
    assert _core(forced.results) == _core(first.results)

    none = run_fleet(logs, cfg, cache_dir=None)
    assert none.counts.skipped == 0 and _core(none.results) == _core(first.results)


def test_cached_result_follows_the_content_not_the_name(logs, tmp_path):
    cfg = load_config(None)
    cache = tmp_path / "cache"
    run_fleet(logs[:1], cfg, cache_dir=cache)
    moved = tmp_path / "elsewhere" / "renamed.tlog"
    moved.parent.mkdir()
    shutil.copy(logs[0], moved)
    again = run_fleet([moved], cfg, cache_dir=cache)
    assert again.counts.skipped == 1
    assert again.results[0]["path"] == str(moved)
    assert again.results[0]["ingest"]["source"] == str(moved)

    # One byte changed: a new key, audited again.
    data = bytearray(moved.read_bytes())
    data[-1] ^= 0xFF
    moved.write_bytes(bytes(data))
    changed = run_fleet([moved], cfg, cache_dir=cache)
    assert changed.counts.skipped == 0 and changed.counts.done == 1


def test_key_depends_on_config_sysid_and_content(logs, tmp_path):
    digest = file_sha256(logs[0])
    base = load_config(None)
    other = config_from_dict({"monitor": {"time_to_alarm_s": 2.0}})
    same = config_from_dict({"monitor": {"time_to_alarm_s": base.monitor.time_to_alarm_s}})
    k = cache_key(digest, config_json(base), None)
    assert len(k) == 64
    assert cache_key(digest, config_json(same), None) == k  # same effective configuration
    assert cache_key(digest, config_json(other), None) != k
    assert cache_key(digest, config_json(base), 1) != k
    assert cache_key(file_sha256(logs[1]), config_json(base), None) != k
    assert len(code_fingerprint()) == 64

    # A changed configuration is a cache miss end to end, and its result differs.
    cache = tmp_path / "cache"
    a = run_fleet(logs[1:2], base, cache_dir=cache)
    b = run_fleet(logs[1:2], other, cache_dir=cache)
    assert b.counts.skipped == 0 and b.counts.done == 1
    assert a.results[0]["fleet"]["key"] != b.results[0]["fleet"]["key"]
    assert b.results[0]["inputs"]["time_to_alarm_s"] == 2.0
    assert run_fleet(logs[1:2], other, cache_dir=cache).counts.skipped == 1


def test_damaged_cache_entry_is_recomputed(logs, tmp_path):
    cfg = load_config(None)
    cache = tmp_path / "cache"
    first = run_fleet(logs[:1], cfg, cache_dir=cache)
    ResultCache(cache).path(first.results[0]["fleet"]["key"]).write_text("{not json")
    again = run_fleet(logs[:1], cfg, cache_dir=cache)
    assert again.counts.skipped == 0 and _core(again.results) == _core(first.results)


def test_cli_workers_progress_cache_and_exit_codes(logs, tmp_path):
    runner = CliRunner()
    cache = tmp_path / "c"
    good = [str(p) for p in logs[:2]]
    args = ["audit", *good, "--workers", "2", "--cache-dir", str(cache), "--json", str(tmp_path / "1.json")]
    r = runner.invoke(main, args)
    assert r.exit_code == 0, r.output
    assert "2/2 files: 2 done, 0 failed, 0 skipped" in r.stderr

    r = runner.invoke(main, args[:-1] + [str(tmp_path / "2.json"), "--fail-on", "caution"])
    assert r.exit_code == 1, r.output  # the cached results still decide --fail-on
    assert "0 done, 0 failed, 2 skipped" in r.stderr
    one, two = (json.loads((tmp_path / n).read_text())["files"] for n in ("1.json", "2.json"))
    assert _core(one) == _core(two)

    r = runner.invoke(main, args + ["--rerun"])
    assert r.exit_code == 0 and "2 done, 0 failed, 0 skipped" in r.stderr

    r = runner.invoke(main, ["audit", *good, str(logs[2]), "--workers", "2", "--cache-dir", str(cache)])
    assert r.exit_code == 2, r.output  # the corrupt file is reported, the others are not lost
    assert "1 failed, 2 skipped" in r.stderr and "UNREADABLE" in r.stdout

    r = runner.invoke(main, ["audit", good[0], "--workers", "2", "--csv", str(tmp_path / "x.csv")])
    assert r.exit_code != 0 and "in this process" in r.output
