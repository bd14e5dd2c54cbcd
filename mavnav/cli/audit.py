"""``mavnav audit PATH...``: headless audit of recorded logs, for CI and fleets.

Exit status: 0 clean; 1 when ``--fail-on`` is met; 2 when an input is
unreadable (the other files are still audited and reported). The same in a
fleet run (:mod:`mavnav.fleet`): ``--workers N`` (local processes),
``--scheduler ADDRESS`` (Dask), ``--fleet-report DIR``, the result cache
(``--cache-dir``, default ``./.mavnav-cache``; ``--rerun``, ``--no-cache``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
import click

from ..errors import MavnavError
from ..fleet.cache import DEFAULT_CACHE_DIR
from . import main
from .honest import check_outputs, honest_audit_result
from .run import common_options
from .viewer_options import viewer_options, viewer_settings, viewer_sinks

_RANK = {"nominal": 0, "caution": 1, "alarm": 2}


def format_table(r: dict) -> str:
    """A readable summary of one file's audit."""
    if "error" in r:
        return f"{r['path']}\n  UNREADABLE: {r['error']}\n"
    lines = [f"{r['path']}"]
    lines.append(f"  duration {r['duration_s']:.1f} s, {r['epochs']} epochs, {r['reboots']} reboots, mode {r['mode']}")
    inp = r["inputs"]
    parts = []
    for k, rate in inp["rates_hz"].items():
        ok = inp["supports_time_to_alarm"][k]
        parts.append(f"{k} {rate:.1f} Hz{'' if ok or rate == 0 else ' (too slow)'}")
    lines.append(f"  inputs: {', '.join(parts)}  [time-to-alarm {inp['time_to_alarm_s']:g} s]")
    av = r["availability"]
    used = av["channels_used"]
    lines.append("  channels used: " + ", ".join(f"{k} {100 * v:.0f}%" for k, v in used.items()))
    ov = av["overall"]
    lines.append("  overall: " + (", ".join(f"{k} {100 * v:.1f}%" for k, v in ov.items() if v > 0)
                                  or ("not applicable" if not r.get("height_integrity_applies", True) else "no epochs")))
    rms = r["fused_vs_autopilot_rms_m"]
    lines.append("  fused vs autopilot height: " + (f"RMS {rms:.2f} m, max {r['fused_vs_autopilot_max_m']:.2f} m"
                                                     if rms is not None else "no autopilot height"))
    alarms = r["alarms"]
    n_alarm = sum(a["state"] == "alarm" for a in alarms)
    lines.append(f"  alarms: {n_alarm} alarm, {len(alarms) - n_alarm} caution")
    for a in alarms[:20]:
        cleared = f"cleared {a['cleared_t_s']:.2f}" if a["cleared_t_s"] is not None else "not cleared"
        lines.append(f"    t={a['t_s']:9.2f} s (boot {a['boot']}) {a['source']:<11} {a['state']:<7} {cleared:<16} {a['reason']}")
    if len(alarms) > 20:
        lines.append(f"    ... {len(alarms) - 20} more (see --json)")
    for n in r["notes"]:
        lines.append(f"  note: {n}")
    return "\n".join(lines) + "\n"


@main.command("audit")
@click.argument("paths", nargs=-1, required=True, type=click.Path())
@click.option("--json", "json_path", type=click.Path(dir_okay=False, writable=True), default=None,
              help="Write the audit of every file as JSON ('-' for stdout).")
@click.option("--fail-on", type=click.Choice(["caution", "alarm"]), default=None,
              help="Exit with status 1 when any file reaches this state.")
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True,
              help="Files audited in parallel on this machine (a local process pool).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the audit on a Dask distributed cluster, e.g. tcp://host:8786 (needs mavnav[fleet]; "
                   "the workers must see the files at the same paths).")
@click.option("--fleet-report", "fleet_report", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Write the fleet summary here: files/alarms/summary.parquet, report.md and PNG plots "
                   "(needs mavnav[fleet]).")
@click.option("--cache-dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help=f"Where fleet runs keep per-file results by content hash [default: ./{DEFAULT_CACHE_DIR}].")
@click.option("--rerun", is_flag=True, default=False,
              help="Audit every file again even if its result is cached (and update the cache).")
@click.option("--no-cache", is_flag=True, default=False, help="Neither read nor write the cache.")
@common_options
@viewer_options
def audit_cmd(paths, json_path, fail_on, workers, scheduler, fleet_report, cache_dir, rerun, no_cache,
              config_path, sysid, csv_path, inject, viewer_flags) -> None:
    """Audit recorded tlogs (files or directories) without a viewer: alarms with
    times and sources, message rates and whether they support the
    time-to-alarm, channel availability, fused height against the
    autopilot's own estimate.

    A fleet run (--workers above 1, --scheduler, --fleet-report, --cache-dir
    or --rerun) audits one file per task, shows its progress on stderr
    (files done, failed, skipped) and skips files whose result is in the
    cache: the key is the SHA-256 of the file's bytes with the effective
    configuration, --sysid and the mavnav version and sources.
    """
    # the audit's own modules (the estimator, numba, scipy) load when it runs, not for --help
    from ..config import load_config
    from ..sim.faults import parse_faults

    cfg = load_config(config_path)
    viewer = viewer_settings(cfg, viewer_flags)
    faults = parse_faults(inject)  # a bad spec fails here, before any work
    check_outputs({"--csv": csv_path, "--rrd": viewer.rrd, "--json": json_path},
                  {"--fleet-report": fleet_report})
    slots = _slots(paths)
    files = [x for x in slots if isinstance(x, Path)]
    missing = [x for x in slots if isinstance(x, dict)]
    fleet = bool(workers > 1 or scheduler or fleet_report or cache_dir or rerun)
    _check_run_kind(paths, files, missing, _wants_in_process(csv_path, viewer), fleet)
    run = None
    if fleet:
        run = _audit_fleet(files, cfg, sysid=sysid, workers=workers, scheduler=scheduler, fleet_report=fleet_report,
                           cache_dir=cache_dir, rerun=rerun, no_cache=no_cache, inject=inject)
        file_results = list(run.results)
    else:
        file_results = _audit_here(files, cfg, sysid=sysid, csv_path=csv_path, faults=faults, viewer=viewer)
    it = iter(file_results)
    results: list[dict] = [x if isinstance(x, dict) else next(it) for x in slots]
    # --sysid with no data from that vehicle is an error; a tlog cut short says where
    results = [honest_audit_result(r, sysid) for r in results]
    for r in results:
        click.echo(format_table(r))
    if json_path:
        _write_json(results, json_path)
    if fleet_report:
        _write_fleet_report(results, fleet_report, run, workers=workers, scheduler=scheduler,
                            config_path=config_path)
    _finish(results, fail_on, run)


def _slots(paths) -> list:
    """The files to audit, in the order of the arguments (a directory's logs
    sorted in its place), a missing path as an error result in its place."""
    from ..ingest import expand_log_paths

    slots: list = []
    for p in paths:
        if Path(p).exists():
            slots += [f for f in expand_log_paths([p]) if f not in slots]
        else:
            slots.append({"path": str(p), "error": "no such file or directory"})
    return slots


def _wants_in_process(csv_path, viewer) -> bool:
    """Whether an output (--csv, a viewer) needs the audit in this process."""
    return bool(csv_path or viewer.rrd or viewer.connect or viewer.viewer != "none")


def _check_run_kind(paths, files: list, missing: list, in_process: bool, fleet: bool) -> None:
    """Refuse an empty run, and in-process outputs with several files or a fleet run."""
    if not files and not missing:
        raise MavnavError("no .tlog, .bin or .ulg files in " + ", ".join(paths))
    if in_process and len(files) != 1:
        raise MavnavError("--csv and the viewer options take exactly one file")
    if in_process and fleet:
        raise MavnavError("--csv and the viewer options audit one file in this process: "
                          "not with --workers, --scheduler, --fleet-report, --cache-dir or --rerun")


def _audit_fleet(files: list, cfg, *, sysid, workers, scheduler, fleet_report, cache_dir, rerun, no_cache,
                 inject):
    """Audit the files as a fleet run (process pool or Dask, with the cache)."""
    from ..fleet import Progress, run_fleet

    if fleet_report:
        from ..fleet.report import _need

        _need("pyarrow.parquet"), _need("matplotlib")  # fail now, not after the whole fleet
    cache = None if no_cache else (cache_dir or DEFAULT_CACHE_DIR)
    return run_fleet(files, cfg, sysid=sysid, workers=workers, scheduler=scheduler, cache_dir=cache,
                     rerun=rerun, progress=Progress(), faults=inject)


def _audit_here(files: list, cfg, *, sysid, csv_path, faults, viewer) -> list[dict]:
    """Audit the files one by one in this process, with the CSV and viewer sinks."""
    from ..fleet.task import audit_one
    from ..sinks.csv_sink import CsvSink

    results: list[dict] = []
    show_bar = len(files) > 1 and sys.stderr.isatty()
    with click.progressbar(files, label="auditing", file=sys.stderr, show_pos=True) if show_bar \
            else _nullbar(files) as bar:
        for f in bar:
            extra = []
            if csv_path:
                extra.append(CsvSink(csv_path))
            extra += viewer_sinks(viewer, live=False)
            results.append(audit_one(f, cfg, sysid=sysid, extra_sinks=extra, faults=faults))
    return results


def _write_json(results: list[dict], json_path: str) -> None:
    doc = json.dumps({"files": results}, indent=1, default=str)
    if json_path == "-":
        click.echo(doc)
    else:
        Path(json_path).write_text(doc, encoding="utf-8")


def _write_fleet_report(results: list[dict], fleet_report, run, *, workers, scheduler, config_path) -> None:
    from ..fleet.report import write_fleet_report

    info = {"backend": run.backend, "workers": workers if not scheduler else f"Dask at {scheduler}",
            "wall time": f"{run.elapsed_s:.1f} s", "config": config_path or "built-in defaults"}
    written = write_fleet_report(results, fleet_report, run_info=info)
    click.echo(f"fleet report: {written['report']}", err=True)


def _finish(results: list[dict], fail_on, run) -> None:
    """Say what was audited on stderr, and exit 2 (unreadable) or 1 (--fail-on met)."""
    from ..audit import worst_state

    unreadable = [r for r in results if "error" in r]
    failed = [r for r in results if "error" not in r and fail_on and _RANK[worst_state(r)] >= _RANK[fail_on]]
    cached = f", {run.counts.skipped} from the cache" if run is not None else ""
    summary = f"audited {len(results)} file(s): {len(unreadable)} unreadable{cached}"
    click.echo(f"{summary}, {len(failed)} reaching --fail-on {fail_on}" if fail_on else summary, err=True)
    if unreadable:
        sys.exit(2)
    if failed:
        sys.exit(1)


class _nullbar:
    def __init__(self, items):
        self.items = items

    def __enter__(self):
        return self.items

    def __exit__(self, *exc):
        return False
