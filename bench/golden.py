"""Golden outputs of ``mavnav audit`` over the real and SITL logs, and a byte
comparison of two such sets: the safety net of a refactoring that must not
change behaviour.

    # write the outputs of the code on PYTHONPATH (or installed) into DIR
    python bench/golden.py run DIR [--more]
    # compare two output directories file by file, byte for byte
    python bench/golden.py compare BEFORE AFTER

``run`` audits each log in its own ``mavnav audit`` process with
``--json``, ``--csv`` and the printed table, and keeps, per log
``NAME.json``, ``NAME.csv``, ``NAME.stdout``, ``NAME.stderr`` and
``NAME.rc`` (the exit status). The logs: every ``.tlog`` in
``../shared/tlogs/real`` and ``../shared/tlogs/other``, every
``.tlog``/``.bin``/``.BIN``/``.ulg`` in ``../shared/flightlogs``, and the
repository's ``sitl_logs/*.tlog``; ``--more`` adds
``~/.cache/mavnav-flightlogs``. The logs are read where they are, never
copied.

Nothing is normalised: the outputs hold the log's absolute path (the same
in both runs) and no wall-clock time. The code audited is the ``mavnav``
that PYTHONPATH (else the installation) names, said on stderr: each audit
runs in the output directory, so that no working directory shadows it. ``compare`` exits 1 when a file
differs or is missing on one side.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"  # beside the repository, read in place
SUFFIXES = {".tlog", ".bin", ".BIN", ".ulg"}


def log_files(more: bool = False) -> list[Path]:
    """The logs of the golden set, in a fixed order."""
    dirs = [(SHARED / "tlogs" / "real", {".tlog"}),
            (SHARED / "tlogs" / "other", {".tlog"}),
            (SHARED / "flightlogs", SUFFIXES),
            (REPO / "sitl_logs", {".tlog"})]
    if more:
        dirs.append((Path.home() / ".cache" / "mavnav-flightlogs", SUFFIXES))
    out: list[Path] = []
    for d, suffixes in dirs:
        if d.is_dir():
            out += sorted(p for p in d.iterdir() if p.is_file() and p.suffix in suffixes)
    return out


def output_stem(path: Path) -> str:
    """One log's output name: its parent folder and file name, flattened."""
    return f"{path.parent.name}__{path.name}"


def run(outdir: Path, more: bool) -> int:
    outdir = outdir.resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    logs = log_files(more)
    probe = subprocess.run([sys.executable, "-c", "import mavnav; print(mavnav.__file__)"], capture_output=True,
                           text=True, env=os.environ.copy(), cwd=outdir)
    print(f"mavnav from {probe.stdout.strip()}", file=sys.stderr)
    for i, log in enumerate(logs, 1):
        stem = outdir / output_stem(log)
        cmd = [sys.executable, "-m", "mavnav.cli", "audit", str(log),
               "--json", f"{stem}.json", "--csv", f"{stem}.csv"]
        # run from the output directory: a working directory holding a mavnav
        # package would shadow the one PYTHONPATH (or the installation) names
        proc = subprocess.run(cmd, capture_output=True, env=os.environ.copy(), cwd=outdir)
        Path(f"{stem}.stdout").write_bytes(proc.stdout)
        Path(f"{stem}.stderr").write_bytes(proc.stderr)
        Path(f"{stem}.rc").write_text(f"{proc.returncode}\n")
        print(f"[{i}/{len(logs)}] {log} -> rc {proc.returncode}", file=sys.stderr)
    return 0


def compare(before: Path, after: Path) -> int:
    names_b = {p.name for p in before.iterdir() if p.is_file()}
    names_a = {p.name for p in after.iterdir() if p.is_file()}
    differ = sorted(n for n in names_b & names_a
                    if not filecmp.cmp(before / n, after / n, shallow=False))
    only_b, only_a = sorted(names_b - names_a), sorted(names_a - names_b)
    for n in differ:
        print(f"DIFFERS: {n}")
    for n in only_b:
        print(f"only in {before}: {n}")
    for n in only_a:
        print(f"only in {after}: {n}")
    same = len(names_b & names_a) - len(differ)
    print(f"{len(names_b | names_a)} files, {same} identical, {len(differ)} differ, "
          f"{len(only_b) + len(only_a)} on one side only")
    return 1 if differ or only_b or only_a else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("outdir", type=Path)
    r.add_argument("--more", action="store_true", help="also ~/.cache/mavnav-flightlogs")
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    a = ap.parse_args()
    if a.cmd == "run":
        return run(a.outdir, a.more)
    return compare(a.before, a.after)


if __name__ == "__main__":
    sys.exit(main())
