"""Digests of what mavnav makes of onboard logs, to show a change left it bit-identical.

For every ``.bin``/``.ulg`` given (files or directories), and with
``--damaged`` for cut and bit-flipped copies of each ULog (fixed cut points
and seeds, written under ``--work-dir``), prints one SHA-256 per file and
part:

* ``record``: the decoded :class:`~mavnav.ingest.onboard.record.OnboardRecord`
  (every array's dtype, shape and bytes; firmware, vehicle, datums,
  message counts, damage lines), or the one-line ``InputError``;
* ``samples``: the ``repr`` of every sample and event of the
  :class:`~mavnav.ingest.onboard.source.OnboardSource` stream (exact floats);
* ``audit``: the ``mavnav audit`` JSON of the file (path reduced to its name).

Run it before and after a change and compare::

    PYTHONPATH=. python bench/onboard_digest.py ../shared/flightlogs --damaged --work-dir /tmp/dmg --out before.json
    # ... change ...
    PYTHONPATH=. python bench/onboard_digest.py ../shared/flightlogs --damaged --work-dir /tmp/dmg --compare before.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import random
import sys
from pathlib import Path

import numpy as np

CUTS = (100, 2_000, 40_000, 0.31, 0.77, -1)  # bytes, fractions of the file, or all but one byte
FLIPS = ((1, 1), (2, 8), (3, 64), (4, 512))  # (seed, bit flips)


def _h(parts) -> str:
    d = hashlib.sha256()
    for p in parts:
        d.update(p if isinstance(p, bytes) else str(p).encode())
        d.update(b"\x00")
    return d.hexdigest()


def record_digest(path: Path) -> str:
    from mavnav.errors import InputError
    from mavnav.ingest.onboard.source import read_record

    try:
        rec = read_record(path)
    except InputError as exc:
        return _h(["InputError", str(exc).replace(str(path), path.name)])
    parts = [rec.format, rec.firmware, rec.vehicle, rec.home_alt_msl_m, rec.origin_alt_msl_m, rec.bytes_read,
             sorted(rec.messages.items()), [d.replace(str(path), path.name) for d in rec.damage]]
    for key in ("imu", "attitude", "baro", "gnss", "rangefinder", "autopilot"):
        s = getattr(rec, key)
        if s is None:
            parts.append(f"{key}: None")
            continue
        for name, v in sorted(vars(s).items()):
            if isinstance(v, np.ndarray):
                parts += [name, v.dtype.str, v.shape, np.ascontiguousarray(v).tobytes()]
            else:
                parts += [name, repr(v)]
    return _h(parts)


def samples_digest(path: Path) -> str:
    from mavnav.config import IngestConfig
    from mavnav.errors import InputError
    from mavnav.ingest.onboard.source import OnboardSource

    try:
        src = OnboardSource(path, IngestConfig())
        items = [repr(s) for s in src]
    except InputError as exc:
        return _h(["InputError", str(exc).replace(str(path), path.name)])
    stats = src.stats.to_dict()
    return _h(items + [json.dumps(stats, sort_keys=True, default=str).replace(str(path), path.name)])


def audit_digest(path: Path) -> str:
    from mavnav.audit import audit_file
    from mavnav.config import config_from_dict
    from mavnav.errors import InputError

    try:
        res = audit_file(path, config_from_dict({}))
    except InputError as exc:
        return _h(["InputError", str(exc).replace(str(path), path.name)])
    text = json.dumps(res, sort_keys=True, default=str)
    return _h([text.replace(str(path), path.name)])


def damaged_copies(src: Path, work: Path) -> list[Path]:
    raw = src.read_bytes()
    out = []
    for cut in CUTS:
        n = len(raw) - 1 if cut == -1 else int(len(raw) * cut) if isinstance(cut, float) else cut
        p = work / f"{src.stem}.cut{n}.ulg"
        p.write_bytes(raw[:n])
        out.append(p)
    for seed, flips in FLIPS:
        rng = random.Random(seed)
        b = bytearray(raw)
        for _ in range(flips):
            i = rng.randrange(16, min(150_000, len(b))) if rng.random() < 0.5 else rng.randrange(16, len(b))
            b[i] ^= 1 << rng.randrange(8)
        p = work / f"{src.stem}.flip{seed}x{flips}.ulg"
        p.write_bytes(bytes(b))
        out.append(p)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--damaged", action="store_true", help="also cut and bit-flipped copies of every .ulg")
    ap.add_argument("--work-dir", type=Path, default=Path("/tmp/mavnav-onboard-digest"))
    ap.add_argument("--no-audit", action="store_true", help="records and samples only")
    ap.add_argument("--out", type=Path, help="write the digests as JSON")
    ap.add_argument("--compare", type=Path, help="compare with digests written earlier by --out")
    args = ap.parse_args(argv)
    files = []
    for p in args.paths:
        p = p.expanduser()
        files += sorted(q for q in p.iterdir() if q.suffix.lower() in (".bin", ".ulg")) if p.is_dir() else [p]
    if args.damaged:
        args.work_dir.mkdir(parents=True, exist_ok=True)
        files += [d for f in list(files) if f.suffix.lower() == ".ulg" for d in damaged_copies(f, args.work_dir)]
    digests = {}
    for f in files:
        row = {"record": record_digest(f), "samples": samples_digest(f)}
        if not args.no_audit:
            row["audit"] = audit_digest(f)
        digests[f.name] = row
        print(f"{f.name:50s} " + " ".join(f"{k} {v[:12]}" for k, v in row.items()), flush=True)
    if args.out:
        args.out.write_text(json.dumps(digests, indent=1, sort_keys=True))
    if args.compare:
        old = json.loads(args.compare.read_text())
        diff = [(n, k) for n, row in digests.items() for k, v in row.items() if old.get(n, {}).get(k) != v]
        missing = sorted(set(old) - set(digests))
        print(f"compared {len(digests)} files with {args.compare}: {len(diff)} differing part(s)"
              + (f", {len(missing)} file(s) not rerun" if missing else ""))
        for n, k in diff:
            print(f"  DIFFERS {n} {k}")
        return 1 if diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
