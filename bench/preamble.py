"""What every benchmark prints first: the command that produced its numbers
(BENCHMARKS.md records it with them) and how busy the machine was."""

from __future__ import annotations

import os
import shlex
import sys


def announce(script: str) -> None:
    """Print ``command: python bench/<script> <args>`` and the cores and load average."""
    print("command:", " ".join(shlex.quote(a) for a in ["python", f"bench/{script}", *sys.argv[1:]]))
    print(f"cores: {os.cpu_count()}, load average before: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


def simulated_samples(path, minutes: float, cfg) -> list:
    """``bench/audit.py``'s simulated flight of ``minutes`` written to ``path``,
    its samples read back, and the pipeline warmed up on them (numba's compiled
    bank, the imports) so that no timing pays for the first call."""
    from audit import generate  # bench/audit.py (this script's own directory)

    from mavnav.ingest import TlogSource
    from mavnav.pipeline import run

    generate(path, minutes)
    samples = list(TlogSource(path, cfg.ingest))
    run(samples[:20000], cfg)
    return samples
