"""The fused height against every raw height on the real flights: how long the
output sat more than ``--margin`` metres from all of them at once (the baro,
the GNSS and the autopilot's own height), by overall state.

    python bench/output_departure.py [--workers 2] [--margin 2.0]

The output may leave one sensor (a fault excluded) or sit between two that
disagree within their sigmas, but an output away from every height the flight
measured is the monitor's own: a filter that took its speed from a glitch and
gated its own sensor, a level given back at a readmission for a step that
never stayed (session 17 found one of each this way). Rows with no such time
are not printed. Time in nominal or caution is what a user would have been
shown as good.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from preamble import announce  # noqa: E402
from realflights import AwaySink, find_flights  # noqa: E402
from scoremetrics import STATES  # noqa: E402

from mavnav.audit import audit_file  # noqa: E402
from mavnav.config import config_from_dict  # noqa: E402
from mavnav.errors import MavnavError  # noqa: E402


def _flight(args):
    path, margin_m = args
    sink = AwaySink()
    try:
        audit_file(path, config_from_dict({}), extra_sinks=[sink])
    except MavnavError as e:
        return path.name, None, str(e)
    got = sink.departure(margin_m)
    return path.name, got, None if got is not None else "no epochs"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--margin", type=float, default=2.0, help="metres from every raw height")
    args = ap.parse_args(argv)
    announce("output_departure.py")
    paths = [p for group in find_flights().values() for p in group]
    print(f"{len(paths)} flights; fused height more than {args.margin:g} m from the baro, the GNSS and the "
          "autopilot at once\n")
    print("| flight | s nominal / caution / unavailable / alarm | largest m (at s) |")
    print("|---|---|---|")
    total = dict.fromkeys(STATES, 0.0)
    with ProcessPoolExecutor(args.workers) as pool:
        for name, res, err in pool.map(_flight, [(p, args.margin) for p in paths]):
            if res is None:
                continue
            secs, worst, at = res
            for s in STATES:
                total[s] += secs[s]
            if sum(secs.values()) > 0:
                print(f"| {name} | {' / '.join(f'{secs[s]:.1f}' for s in STATES)} | {worst:.2f} ({at:.1f}) |")
    print(f"\nTotal: {' / '.join(f'{total[s]:.1f}' for s in STATES)} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
