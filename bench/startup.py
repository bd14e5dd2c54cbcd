"""CLI start-up against a bare ``import pymavlink.mavutil``, in the same run.

Each command is a fresh interpreter (``sys.executable``, the environment of
this script, so ``PYTHONPATH`` picks the tree under test), timed from spawn
to exit; the runs are interleaved (bare, then each command, ``--repeat``
times) so machine load hits all of them alike, and the median and the best
of each are compared with the bare import's:

* bare: ``python -c "import pymavlink.mavutil"``;
* ``mavnav --help``, ``mavnav audit --help`` (and ``run``/``replay``
  ``--help``, for the record): ``python -m mavnav.cli ...``, what the
  ``mavnav`` script runs.

Goal (issue 15): every ``--help`` within 1.5x of the bare import.

    .venv/bin/python bench/startup.py [--repeat 15]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

from preamble import announce  # bench/preamble.py (this script's own directory)

COMMANDS = {
    "bare import pymavlink.mavutil": ["-c", "import pymavlink.mavutil"],
    "mavnav --help": ["-m", "mavnav.cli", "--help"],
    "mavnav audit --help": ["-m", "mavnav.cli", "audit", "--help"],
    "mavnav run --help": ["-m", "mavnav.cli", "run", "--help"],
    "mavnav replay --help": ["-m", "mavnav.cli", "replay", "--help"],
}
GOAL = 1.5


def once(args: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    announce("startup.py")
    print(f"python {sys.executable}, PYTHONPATH={os.environ.get('PYTHONPATH', '')}")
    for a in COMMANDS.values():  # page cache and .pyc warm-up, not timed
        once(a)
    times: dict[str, list[float]] = {k: [] for k in COMMANDS}
    for _ in range(args.repeat):
        for k, a in COMMANDS.items():
            times[k].append(once(a))
    base = list(COMMANDS)[0]
    b_med, b_min = statistics.median(times[base]), min(times[base])
    print(f"{'':32} {'median':>8} {'best':>8}   ratio median / best   (goal <= {GOAL}x)")
    for k, ts in times.items():
        med, best = statistics.median(ts), min(ts)
        verdict = "" if k == base else ("met" if med / b_med <= GOAL else "MISSED")
        print(f"{k:32} {med:7.3f}s {best:7.3f}s   {med / b_med:5.2f}x / {best / b_min:5.2f}x   {verdict}")
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
