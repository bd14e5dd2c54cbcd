"""Golden outputs: ``mavnav audit`` of the repository's own simulator logs
(``sitl_logs/*.tlog``), byte for byte, against the files stored in
``tests/golden/``.

Per log ``NAME.tlog`` three files: ``NAME.json`` (``--json``), ``NAME.csv``
(``--csv``) and ``NAME.stdout`` (the printed table). The audit runs in this
process, from the repository's root, on the relative path
``sitl_logs/NAME.tlog``, so the outputs name the log the same way wherever
the repository is checked out; they hold no wall-clock time.

A refactor must leave them unchanged (``tests/test_golden.py`` fails and
shows the first differing lines). A change of behaviour that is meant
rewrites them, and the diff of ``tests/golden/`` shows what changed:

    make golden          # = python -m tests.support.golden

Same code, numpy, numba and pymavlink: same bytes (as ``sitl_logs/``
itself, see its README).
"""

from __future__ import annotations

import difflib
import os
import sys
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "tests" / "golden"
LOGS = tuple(sorted(p.name for p in (REPO / "sitl_logs").glob("*.tlog")))
SUFFIXES = ("json", "csv", "stdout")
REGENERATE = "make golden  (or: python -m tests.support.golden)"


@contextmanager
def _in_repo():
    old = os.getcwd()
    os.chdir(REPO)
    try:
        yield
    finally:
        os.chdir(old)


def audit_outputs(log: str, outdir: Path) -> dict[str, bytes]:
    """The audit's JSON, CSV and printed table of ``sitl_logs/<log>``, by suffix."""
    from click.testing import CliRunner

    from mavnav.cli import main

    stem = Path(log).stem
    js, csv = Path(outdir).resolve() / f"{stem}.json", Path(outdir).resolve() / f"{stem}.csv"
    with _in_repo():
        res = CliRunner().invoke(main, ["audit", f"sitl_logs/{log}", "--json", str(js), "--csv", str(csv)])
    if res.exit_code != 0:
        raise RuntimeError(f"mavnav audit sitl_logs/{log}: exit {res.exit_code}\n{res.output}") from res.exception
    return {"json": js.read_bytes(), "csv": csv.read_bytes(), "stdout": res.stdout_bytes}


def expected_path(log: str, suffix: str) -> Path:
    return GOLDEN / f"{Path(log).stem}.{suffix}"


def first_differences(expected: bytes, actual: bytes, name: str, n: int = 30) -> str:
    """The first ``n`` lines of a unified diff of two outputs."""
    diff = difflib.unified_diff(expected.decode(errors="replace").splitlines(),
                                actual.decode(errors="replace").splitlines(),
                                f"expected/{name}", f"actual/{name}", lineterm="", n=1)
    lines = list(diff)
    more = f"\n... {len(lines) - n} more diff lines" if len(lines) > n else ""
    return "\n".join(lines[:n]) + more


def regenerate(outdir: Path = GOLDEN) -> list[Path]:
    """Write the outputs of the code imported now as the expected files."""
    import tempfile

    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    with tempfile.TemporaryDirectory() as tmp:
        for log in LOGS:
            for suffix, data in audit_outputs(log, Path(tmp)).items():
                p = outdir / f"{Path(log).stem}.{suffix}"
                p.write_bytes(data)
                written.append(p)
    return written


if __name__ == "__main__":
    for p in regenerate():
        print(p.relative_to(REPO), file=sys.stderr)
