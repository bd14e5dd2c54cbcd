"""Fleet summary: Parquet tables and a Markdown report with PNG plots.

``write_fleet_report(results, DIR)`` writes:

* ``files.parquet``: one row per file (status, duration, worst state, alarm
  counts per source, input rates against what the time-to-alarm needs,
  fused-vs-autopilot RMS and max, availability, error);
* ``alarms.parquet``: one row per caution/alarm episode (file, boot, time,
  source, state, ``kind`` = the reason without its numbers, reason, duration);
* ``summary.parquet``: alarms by source, state and kind (episodes, files, median
  and max episode duration, episodes never cleared);
* ``report.md`` with the tables that matter and ``*.png`` plots of the fleet
  distribution (matplotlib, Agg backend).

Needs pyarrow and matplotlib (``pip install 'mavnav[fleet]'``).
"""

from __future__ import annotations

import math
import re
import statistics
from collections import Counter, defaultdict
from pathlib import Path
from typing import Optional, Sequence

from ..audit import worst_state
from ..errors import MavnavError
from ..report import SOURCES
from ..sensors import INPUTS

STATES = ("nominal", "caution", "unavailable", "alarm")
_PAREN = re.compile(r"\s*\([^()]*\)")
_NUMBER = re.compile(r"(?<![\w.])[+-]?\d+(?:\.\d+)?(?:e[+-]?\d+)?")


def alarm_kind(reason: str) -> str:
    """An alarm's reason without its numbers and details, to group episodes:
    ``"innovations too large over 5 s (sum 76 > 73) (baro in the GNSS channel)"``
    gives ``"innovations too large over # s"``, ``"rng-baro -3.03 m, threshold 2.99 m"``
    gives ``"rng-baro # m"``."""
    text = _PAREN.sub("", reason or "")
    text = re.split(r"[:,;]", text, maxsplit=1)[0]
    text = " ".join(_NUMBER.sub("#", text).split())
    return text or "?"


def _need(mod: str):
    try:
        return __import__(mod, fromlist=["_"])
    except ImportError:
        raise MavnavError(f"--fleet-report needs {mod.split('.')[0]}: pip install 'mavnav[fleet]'") from None


# ---------------------------------------------------------------- rows


def file_rows(results: Sequence[dict]) -> list[dict]:
    rows = []
    for r in results:
        fl = r.get("fleet", {})
        row = {"path": r["path"], "sha256": fl.get("sha256"), "cached": bool(fl.get("cached", False)),
               "status": "error" if "error" in r else "ok", "error": r.get("error")}
        if "error" not in r:
            alarms = r.get("alarms", [])
            inp = r["inputs"]
            ov = r["availability"]["overall"]
            row.update(
                duration_s=r["duration_s"], epochs=r["epochs"], reboots=r["reboots"], mode=r["mode"],
                worst_state=worst_state(r),
                alarm_episodes=sum(a["state"] == "alarm" for a in alarms),
                caution_episodes=sum(a["state"] == "caution" for a in alarms),
                first_alarm_t_s=min((a["t_s"] for a in alarms if a["state"] == "alarm"), default=None),
                time_to_alarm_s=inp["time_to_alarm_s"],
                fused_vs_autopilot_rms_m=r["fused_vs_autopilot_rms_m"],
                fused_vs_autopilot_max_m=r["fused_vs_autopilot_max_m"],
                slow_inputs=",".join(k for k in INPUTS if inp["rates_hz"].get(k, 0) > 0
                                     and not inp["supports_time_to_alarm"].get(k, True)),
                missing_inputs=",".join(k for k in INPUTS if inp["rates_hz"].get(k, 0) == 0),
                **{f"overall_{s}": ov.get(s) for s in STATES},
            )
            for src in SOURCES:
                row[f"alarms_{src}"] = sum(a["source"] == src and a["state"] == "alarm" for a in alarms)
                row[f"cautions_{src}"] = sum(a["source"] == src and a["state"] == "caution" for a in alarms)
            for k in INPUTS:
                row[f"rate_{k}_hz"] = inp["rates_hz"].get(k)
                row[f"required_{k}_hz"] = inp["required_hz"].get(k)
                row[f"supports_{k}"] = inp["supports_time_to_alarm"].get(k)
        rows.append(row)
    return rows


def alarm_rows(results: Sequence[dict]) -> list[dict]:
    rows = []
    for r in results:
        for a in r.get("alarms", []):
            cleared = a.get("cleared_t_s")
            rows.append({"path": r["path"], "boot": a["boot"], "t_s": a["t_s"], "source": a["source"],
                         "state": a["state"], "kind": alarm_kind(a["reason"]), "reason": a["reason"],
                         "cleared_t_s": cleared,
                         "duration_s": round(cleared - a["t_s"], 6) if cleared is not None else None})
    return rows


def summary_rows(alarms: Sequence[dict]) -> list[dict]:
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for a in alarms:
        groups[(a["source"], a["state"], a["kind"])].append(a)
    rows = []
    for (src, state, kind), items in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        durs = [a["duration_s"] for a in items if a["duration_s"] is not None]
        rows.append({"source": src, "state": state, "kind": kind, "episodes": len(items),
                     "files": len({a["path"] for a in items}),
                     "median_duration_s": round(statistics.median(durs), 3) if durs else None,
                     "max_duration_s": round(max(durs), 3) if durs else None,
                     "never_cleared": sum(a["duration_s"] is None for a in items)})
    return rows



def _table(pa, rows: list[dict], schema):
    return pa.Table.from_pylist(rows, schema=schema)


def _schemas(pa):
    f64, i64, s, b = pa.float64(), pa.int64(), pa.string(), pa.bool_()
    files = [("path", s), ("sha256", s), ("cached", b), ("status", s), ("error", s), ("duration_s", f64),
             ("epochs", i64), ("reboots", i64), ("mode", s), ("worst_state", s), ("alarm_episodes", i64),
             ("caution_episodes", i64), ("first_alarm_t_s", f64), ("time_to_alarm_s", f64),
             ("fused_vs_autopilot_rms_m", f64), ("fused_vs_autopilot_max_m", f64), ("slow_inputs", s),
             ("missing_inputs", s)]
    files += [(f"overall_{st}", f64) for st in STATES]
    for src in SOURCES:
        files += [(f"alarms_{src}", i64), (f"cautions_{src}", i64)]
    for k in INPUTS:
        files += [(f"rate_{k}_hz", f64), (f"required_{k}_hz", f64), (f"supports_{k}", b)]
    alarms = [("path", s), ("boot", i64), ("t_s", f64), ("source", s), ("state", s), ("kind", s), ("reason", s),
              ("cleared_t_s", f64), ("duration_s", f64)]
    summary = [("source", s), ("state", s), ("kind", s), ("episodes", i64), ("files", i64),
               ("median_duration_s", f64), ("max_duration_s", f64), ("never_cleared", i64)]
    return {n: pa.schema(cols) for n, cols in (("files", files), ("alarms", alarms), ("summary", summary))}


def fleet_tables(results: Sequence[dict]) -> dict:
    """The three tables as ``pyarrow.Table``: ``files``, ``alarms``, ``summary``."""
    pa = _need("pyarrow")
    sch = _schemas(pa)
    al = alarm_rows(results)
    return {"files": _table(pa, file_rows(results), sch["files"]),
            "alarms": _table(pa, al, sch["alarms"]),
            "summary": _table(pa, summary_rows(al), sch["summary"])}


# ---------------------------------------------------------------- plots


def _plots(outdir: Path, files: list[dict], alarms: list[dict]) -> list[tuple[str, str]]:
    matplotlib = _need("matplotlib")
    matplotlib.use("Agg", force=True)
    plt = _need("matplotlib.pyplot")
    ok = [f for f in files if f["status"] == "ok"]
    _plot_alarms_by_source(plt, outdir, ok, alarms)
    _plot_autopilot_disagreement(plt, outdir, ok)
    _plot_input_rates(plt, outdir, ok)
    _plot_availability(plt, outdir, ok)
    return [("alarms_by_source.png", "Caution and alarm episodes by source"),
            ("autopilot_disagreement.png", "Disagreement with the autopilot's height"),
            ("input_rates.png", "Input rates per file"),
            ("availability.png", "Overall availability per file")]


def _plot_alarms_by_source(plt, outdir: Path, ok: list[dict], alarms: list[dict]) -> None:
    fig, ax = plt.subplots(figsize=(7, 3.5))
    by = Counter((a["source"], a["state"]) for a in alarms)
    x = range(len(SOURCES))
    c = [by[(s, "caution")] for s in SOURCES]
    a_ = [by[(s, "alarm")] for s in SOURCES]
    ax.bar(x, c, label="caution", color="#e0a030")
    ax.bar(x, a_, bottom=c, label="alarm", color="#c03030")
    ax.set_xticks(list(x), SOURCES)
    ax.set_ylabel("episodes")
    ax.set_title(f"Cautions and alarms by source ({len(ok)} files)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(outdir / "alarms_by_source.png", dpi=90)
    plt.close(fig)


def _plot_autopilot_disagreement(plt, outdir: Path, ok: list[dict]) -> None:
    fig, ax = plt.subplots(figsize=(7, 3.5))
    mx = [f["fused_vs_autopilot_max_m"] for f in ok if f.get("fused_vs_autopilot_max_m") is not None]
    rms = [f["fused_vs_autopilot_rms_m"] for f in ok if f.get("fused_vs_autopilot_rms_m") is not None]
    if mx:
        hi = max(max(mx), 1e-3)
        bins = [hi * i / 20 for i in range(21)]
        ax.hist(mx, bins=bins, alpha=0.7, label="max |fused - autopilot|")
        ax.hist(rms, bins=bins, alpha=0.7, label="RMS")
        ax.legend()
    else:
        ax.text(0.5, 0.5, "no file with an autopilot height", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("m")
    ax.set_ylabel("files")
    ax.set_title("Fused height against the autopilot's own, per file")
    fig.tight_layout()
    fig.savefig(outdir / "autopilot_disagreement.png", dpi=90)
    plt.close(fig)


def _plot_input_rates(plt, outdir: Path, ok: list[dict]) -> None:
    fig, axes = plt.subplots(1, len(INPUTS), figsize=(10, 3.2))
    for ax, k in zip(axes, INPUTS):
        rates = [f[f"rate_{k}_hz"] for f in ok if f.get(f"rate_{k}_hz") is not None]
        need = next((f[f"required_{k}_hz"] for f in ok if f.get(f"required_{k}_hz") is not None), None)
        if rates:
            ax.hist(rates, bins=15, color="#4070b0")
        if need is not None:
            ax.axvline(need, color="#c03030", ls="--", label=f"needs {need:g} Hz")
            ax.legend(fontsize=7)
        ax.set_title(k)
        ax.set_xlabel("Hz")
    axes[0].set_ylabel("files")
    fig.suptitle("Input rates against what the time-to-alarm needs")
    fig.tight_layout()
    fig.savefig(outdir / "input_rates.png", dpi=90)
    plt.close(fig)


def _plot_availability(plt, outdir: Path, ok: list[dict]) -> None:
    fig, ax = plt.subplots(figsize=(7, 3.5))
    nom = [100 * f["overall_nominal"] for f in ok if f.get("overall_nominal") is not None]
    if nom:
        ax.hist(nom, bins=[5 * i for i in range(21)], color="#40a060")
    ax.set_xlabel("% of epochs with the overall state nominal")
    ax.set_ylabel("files")
    ax.set_title("Overall availability per file")
    fig.tight_layout()
    fig.savefig(outdir / "availability.png", dpi=90)
    plt.close(fig)


# ---------------------------------------------------------------- markdown


def _md_table(header: Sequence[str], rows: list[Sequence]) -> str:
    def cell(v):
        if v is None:
            return ""
        if isinstance(v, float):
            return f"{v:.3g}" if math.isfinite(v) else str(v)
        return str(v).replace("|", "\\|")
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in r) + " |" for r in rows]
    return "\n".join(lines)


def _markdown(files: list[dict], alarms: list[dict], summary: list[dict], plots, run_info: dict) -> str:
    ok = [f for f in files if f["status"] == "ok"]
    bad = [f for f in files if f["status"] != "ok"]
    md = _md_overview(files, ok, bad, run_info)
    md += ["## Alarms by source and kind", ""]
    md.append(_md_table(["source", "state", "kind", "episodes", "files", "median s", "max s", "never cleared"],
                        [[r["source"], r["state"], r["kind"], r["episodes"], r["files"], r["median_duration_s"],
                          r["max_duration_s"], r["never_cleared"]] for r in summary]) if summary else "None.")
    md += _md_rates(ok)
    md += _md_autopilot(ok)
    md += _md_most_alarms(ok)
    if bad:
        md += ["", "## Unreadable files", ""]
        md.append(_md_table(["file", "error"], [[f["path"], f["error"]] for f in bad]))
    md += ["", "## Plots", ""]
    md += [f"![{title}]({name})\n" for name, title in plots]
    md += ["", "Tables: `files.parquet` (one row per file), `alarms.parquet` (one row per episode), "
               "`summary.parquet` (the alarms table above).", ""]
    return "\n".join(md)


def _md_overview(files: list[dict], ok: list[dict], bad: list[dict], run_info: dict) -> list[str]:
    worst = Counter(f["worst_state"] for f in ok)
    hours = sum(f["duration_s"] for f in ok) / 3600
    md = ["# mavnav fleet audit", ""]
    md.append(f"{len(files)} files ({hours:.2f} h of logs): {len(ok)} audited, {len(bad)} unreadable; "
              f"{sum(f['cached'] for f in files)} results from the cache.")
    if run_info:
        md.append("")
        md.append(", ".join(f"{k}: {v}" for k, v in run_info.items()))
    md += ["", f"Worst state reached per file: {worst.get('alarm', 0)} alarm, {worst.get('caution', 0)} caution, "
               f"{worst.get('nominal', 0)} nominal.", ""]
    return md


def _md_rates(ok: list[dict]) -> list[str]:
    tta = sorted({f["time_to_alarm_s"] for f in ok})
    md = ["", "## Input rates that cannot support the time-to-alarm", "",
          f"Time-to-alarm: {', '.join(f'{t:g} s' for t in tta) or 'n/a'}. Files whose average rate is below "
          f"90 % of what it needs (an input with no samples at all is counted apart).", ""]
    rows = []
    for k in INPUTS:
        slow = [f for f in ok if k in (f["slow_inputs"] or "").split(",")]
        missing = [f for f in ok if k in (f["missing_inputs"] or "").split(",")]
        rates = [f[f"rate_{k}_hz"] for f in ok if f[f"rate_{k}_hz"]]
        rows.append([k, next((f[f"required_{k}_hz"] for f in ok), None), len(slow), len(missing),
                     statistics.median(rates) if rates else None, ", ".join(Path(f["path"]).name for f in slow[:5])
                     + (" ..." if len(slow) > 5 else "")])
    md.append(_md_table(["input", "needs Hz", "files too slow", "files without", "median Hz", "e.g."], rows))
    return md


def _md_autopilot(ok: list[dict]) -> list[str]:
    md = ["", "## Worst disagreement with the autopilot's own height", ""]
    cmp_ = sorted((f for f in ok if f["fused_vs_autopilot_max_m"] is not None),
                  key=lambda f: -f["fused_vs_autopilot_max_m"])
    md.append(_md_table(["file", "max m", "RMS m", "worst state"],
                        [[f["path"], f["fused_vs_autopilot_max_m"], f["fused_vs_autopilot_rms_m"], f["worst_state"]]
                         for f in cmp_[:10]]) if cmp_ else "No file has an autopilot height.")
    return md


def _md_most_alarms(ok: list[dict]) -> list[str]:
    md = ["", "## Files with the most alarms", ""]
    top = sorted((f for f in ok if f["alarm_episodes"] or f["caution_episodes"]),
                 key=lambda f: (-f["alarm_episodes"], -f["caution_episodes"]))[:10]
    md.append(_md_table(["file", "alarms", "cautions", "first alarm t s", "duration s"],
                        [[f["path"], f["alarm_episodes"], f["caution_episodes"], f["first_alarm_t_s"],
                          f["duration_s"]] for f in top]) if top else "None.")
    return md


def write_fleet_report(results: Sequence[dict], outdir: str | Path, run_info: Optional[dict] = None) -> dict:
    """Write the Parquet tables, the plots and ``report.md`` into ``outdir``; returns their paths."""
    pq = _need("pyarrow.parquet")
    outdir = Path(outdir)
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise MavnavError(f"{outdir}: cannot create the report directory ({exc.strerror or exc})") from None
    tables = fleet_tables(results)
    written = {}
    for name, t in tables.items():
        p = outdir / f"{name}.parquet"
        pq.write_table(t, p)
        written[name] = p
    files, alarms, summary = (tables[n].to_pylist() for n in ("files", "alarms", "summary"))
    plots = _plots(outdir, files, alarms)
    for name, _ in plots:
        written[name] = outdir / name
    p = outdir / "report.md"
    p.write_text(_markdown(files, alarms, summary, plots, run_info or {}), encoding="utf-8")
    written["report"] = p
    return written
