"""Where the tests find the repository's files and the shared real logs.

The shared data (``../shared`` beside the repository) is read in place at run
time, never copied into the repository.
"""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
SCENARIOS = CONFIG / "scenarios"
SITL_LOGS = REPO / "sitl_logs"  # the small simulated flights bundled with the repository
BENCH = REPO / "bench"

SHARED = REPO.parent / "shared"
SHARED_TLOGS = SHARED / "tlogs"
SHARED_FLIGHTLOGS = SHARED / "flightlogs"
