"""Fleet audit throughput: files per second for 1 and 2 workers, in one run.

Copies the bundled ``sitl_logs/*.tlog`` (60-90 s flights, 0.3-0.9 MB) ``--copies``
times into a temporary directory (each copy one byte different, so none is
the same file to a cache) and audits them with the cache off:

* ``serial``: in this process (``--workers 1``, no pool to start);
* ``processes``, 1 and 2 workers: the local process pool of ``--workers N``,
  start-up included;
* with ``--dask``, a ``distributed.LocalCluster`` of 1 and 2 worker processes
  (``--scheduler``), cluster start-up excluded.

Prints files/s, the scaling ratio (2 workers / 1 worker), the cores the run
actually got (CPU seconds / wall seconds) and the load average: on a shared
machine the ratio is bounded by the cores left free. Usage::

    .venv/bin/python bench/fleet.py [--copies 6] [--dask]

``--logs PATH...`` audits those logs (files or directories, e.g. the
real-flight corpus: ``../shared/tlogs/real ../shared/tlogs/other
../shared/flightlogs ~/.cache/mavnav-flightlogs``) instead of the copies,
in place; ``--no-serial`` skips the in-process run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from preamble import announce  # bench/preamble.py (this script's own directory)
from mavnav.config import load_config
from mavnav.fleet import run_fleet

REPO = Path(__file__).resolve().parents[1]


def make_fleet(dest: Path, copies: int) -> list[Path]:
    out = []
    for i in range(copies):
        for src in sorted((REPO / "sitl_logs").glob("*.tlog")):
            p = dest / f"{src.stem}_{i:03d}.tlog"
            shutil.copy(src, p)
            with open(p, "ab") as f:  # a distinct file; a trailing byte is garbage the reader skips
                f.write(bytes([i % 256]))
            out.append(p)
    return out


def timed(files, **kw) -> tuple[float, float]:
    """Wall seconds of one run and the CPU seconds its tasks used (each task measures its own)."""
    t0 = time.perf_counter()
    run = run_fleet(files, load_config(None), cache_dir=None, **kw)
    dt = time.perf_counter() - t0
    assert run.counts.failed == 0, [r for r in run.results if "error" in r][:1]
    return dt, sum(r["fleet"]["cpu_s"] for r in run.results)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--copies", type=int, default=6, help="copies of each sitl_logs tlog (6 logs each)")
    ap.add_argument("--dask", action="store_true", help="also on a distributed.LocalCluster")
    ap.add_argument("--logs", nargs="+", default=None, metavar="PATH", help="audit these logs instead of copies")
    ap.add_argument("--no-serial", action="store_true", help="skip the in-process run")
    args = ap.parse_args()
    announce("fleet.py")
    with tempfile.TemporaryDirectory() as tmp:
        if args.logs:
            from mavnav.ingest import expand_log_paths

            files = expand_log_paths([os.path.expanduser(p) for p in args.logs])
        else:
            files = make_fleet(Path(tmp), args.copies)
        mb = sum(f.stat().st_size for f in files) / 1e6
        print(f"{len(files)} files, {mb:.1f} MB")
        timed(files[:2], backend="serial")  # warm numba's cache and the imports in this process
        rows = []
        if not args.no_serial:
            dt, cpu = timed(files, backend="serial")
            rows.append(("serial (in process)", 1, dt, cpu))
        for w in (1, 2):
            dt, cpu = timed(files, workers=w, backend="processes")
            rows.append(("processes (--workers N)", w, dt, cpu))
        if args.dask:
            import distributed

            for w in (1, 2):
                with distributed.LocalCluster(n_workers=w, threads_per_worker=1, processes=True,
                                              dashboard_address=None, silence_logs=40) as c:
                    timed(files[:w * 2], scheduler=c.scheduler_address)  # start the workers' imports
                    dt, cpu = timed(files, scheduler=c.scheduler_address)
                rows.append(("dask LocalCluster (--scheduler)", w, dt, cpu))
        # cores used = the tasks' CPU s / wall s: below the worker count, the
        # workers did not get the cores (shared machine) or waited on start-up.
        print(f"{'backend':<34}{'workers':>8}{'wall s':>9}{'files/s':>9}{'MB/s':>8}{'cores used':>11}")
        for name, w, dt, cpu in rows:
            used = f"{cpu / dt:>11.2f}" if cpu is not None else f"{'-':>11}"
            print(f"{name:<34}{w:>8}{dt:>9.2f}{len(files) / dt:>9.2f}{mb / dt:>8.2f}{used}")
        by = {(n, w): dt for n, w, dt, _ in rows}
        for name in dict.fromkeys(n for n, _, _, _ in rows):
            if (name, 1) in by and (name, 2) in by:
                print(f"scaling {name}: 2 workers / 1 worker = {by[(name, 1)] / by[(name, 2)]:.2f}x")
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
