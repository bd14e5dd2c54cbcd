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
