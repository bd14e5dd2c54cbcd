"""Honest exits: refuse work whose result could not be kept, and never report a
log that was not audited as if it were.

* :func:`check_outputs`: every output path is checked before any work starts
  (one line on stderr, exit 2 via :class:`~mavnav.errors.MavnavError`),
  instead of a traceback or a warning after the work.
* :func:`no_vehicle_error`: ``--sysid N`` and no data from system N is an
  error naming the vehicles that were seen (with their heartbeats), not "0
  epochs" and exit 0.
* :func:`truncation_note`: a tlog that ends mid-record says where.
"""

from __future__ import annotations

import tempfile
from collections import Counter
from pathlib import Path
from typing import Dict, Optional, Tuple, Union

from ..errors import InputError, MavnavError

PathLike = Union[str, Path]

HEARTBEAT = 0
_MAV_TYPE_GCS = 6
_AUTOPILOT_NAMES = {0: "generic", 3: "ArduPilot", 8: "no autopilot", 12: "PX4"}


def _probe_dir(d: Path, what: str, shown: PathLike) -> None:
    try:
        tempfile.TemporaryFile(dir=d).close()
    except OSError as exc:
        raise MavnavError(f"{what} {shown}: cannot write in {d} ({exc.strerror})") from None


def check_writable(path: PathLike, what: str) -> None:
    """Raise :class:`MavnavError` unless the file ``path`` can be created or overwritten.

    An existing file is opened for appending (its bytes untouched); for a new
    one, its directory must exist and take a new file (a temporary file is
    created and removed there, so the check holds for root too)."""
    p = Path(path)
    if p.is_dir():
        raise MavnavError(f"{what} {path}: is a directory")
    if p.exists():
        try:
            open(p, "ab").close()
        except OSError as exc:
            raise MavnavError(f"{what} {path}: cannot write ({exc.strerror})") from None
        return
    parent = p.parent
    if not parent.exists():
        raise MavnavError(f"{what} {path}: no such directory {parent}")
    if not parent.is_dir():
        raise MavnavError(f"{what} {path}: {parent} is not a directory")
    _probe_dir(parent, what, path)


def check_writable_dir(path: PathLike, what: str) -> None:
    """Raise :class:`MavnavError` unless the directory ``path`` exists and takes new files,
    or can be created (its nearest existing ancestor is a writable directory)."""
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise MavnavError(f"{what} {path}: not a directory")
        _probe_dir(p, what, path)
        return
    q = p.parent
    while not q.exists() and q != q.parent:
        q = q.parent
    if not q.is_dir():
        raise MavnavError(f"{what} {path}: {q} is not a directory")
    _probe_dir(q, what, path)


def check_outputs(files: Dict[str, Optional[PathLike]] = None, dirs: Dict[str, Optional[PathLike]] = None) -> None:
    """Check every output given (``{option: path or None}``; ``-`` is stdout) before any work."""
    for what, path in (files or {}).items():
        if path is not None and str(path) != "-":
            check_writable(path, what)
    for what, path in (dirs or {}).items():
        if path is not None:
            check_writable_dir(path, what)


# ------------------------------------------------------------------ tlog facts


def scan_tlog(path: PathLike) -> Tuple[Dict[int, dict], Optional[int]]:
    """One pass over a tlog: ``({sysid: {"heartbeats", "type", "autopilot", "frames"}}, truncated_at)``,
    ``truncated_at`` the byte offset of a record the end of the file cuts short (or None)."""
    from ..ingest import wire
    from ..ingest.tlog_reader import TlogReader

    reader = TlogReader(path, {HEARTBEAT})
    decode = wire.make_decoder(HEARTBEAT)
    seen: Dict[int, dict] = {}
    for item in reader:
        if type(item) is tuple:
            _, _, sysid, _, payload = item
            f = decode(payload)
            v = seen.setdefault(sysid, {"heartbeats": 0, "type": f["type"], "autopilot": f["autopilot"]})
            v["heartbeats"] += 1
    frames: Counter = Counter()
    for (sysid, _), n in reader.counts.items():
        frames[sysid] += n
    for sysid, n in frames.items():
        seen.setdefault(sysid, {"heartbeats": 0, "type": None, "autopilot": None})["frames"] = n
    return dict(sorted(seen.items())), reader.truncated_at


def _type_name(t: Optional[int]) -> str:
    if t is None:
        return "no heartbeat"
    try:
        from pymavlink.dialects.v20 import ardupilotmega as d

        return d.enums["MAV_TYPE"][t].name.replace("MAV_TYPE_", "").lower()
    except (KeyError, AttributeError):
        return f"type {t}"


def describe_vehicles(seen: Dict[int, dict]) -> str:
    """``sysid 1 (ArduPilot quadrotor, 812 heartbeats), sysid 255 (gcs, 40 heartbeats)``."""
    if not seen:
        return "none"
    parts = []
    for sysid, v in seen.items():
        if v["heartbeats"]:
            who = _type_name(v["type"])
            if v["type"] != _MAV_TYPE_GCS:
                who = f"{_AUTOPILOT_NAMES.get(v['autopilot'], 'autopilot ' + str(v['autopilot']))} {who}"
            parts.append(f"sysid {sysid} ({who}, {v['heartbeats']} heartbeats)")
        else:
            parts.append(f"sysid {sysid} (no heartbeat, {v.get('frames', 0)} frames)")
    return ", ".join(parts)


def no_vehicle_error(path: PathLike, sysid: int, fmt: str = "tlog") -> str:
    """The one-line error for ``--sysid`` naming a system that sent no data in ``path``."""
    if fmt != "tlog":
        return f"no data from --sysid {sysid} in this {fmt} log"
    try:
        seen, _ = scan_tlog(path)
    except (OSError, InputError):
        return f"no data from --sysid {sysid}"
    return f"no data from --sysid {sysid}; vehicles seen: {describe_vehicles(seen)}"


def has_vehicle_data(stats: dict) -> bool:
    """Whether the source's statistics (``IngestStats.to_dict()``) hold any sample of the vehicle."""
    return any(n > 0 for n in (stats.get("samples") or {}).values())


def truncation_note(path: PathLike) -> Optional[str]:
    """``ends mid-record at byte N (M bytes cut off)`` for a tlog cut short, else None."""
    try:
        _, at = scan_tlog(path)
        size = Path(path).stat().st_size
    except (OSError, InputError):
        return None
    if at is None:
        return None
    return f"ends mid-record at byte {at} ({size - at} bytes of an incomplete record)"


def honest_audit_result(result: dict, sysid: Optional[int]) -> dict:
    """An audit result as it should be reported: an error if ``--sysid`` saw no data,
    a note if the tlog ends mid-record (the file is scanned again only then)."""
    if "error" in result:
        return result
    ingest = result.get("ingest") or {}
    fmt = ingest.get("format", "tlog")
    path = ingest.get("source") or result["path"]
    if sysid is not None and not has_vehicle_data(ingest):
        return {"path": result["path"], "error": no_vehicle_error(path, sysid, fmt)}
    if fmt == "tlog" and (ingest.get("rejected") or {}).get("truncated"):
        note = truncation_note(path)
        if note and note not in result.get("notes", []):
            result.setdefault("notes", []).append(note)
    return result
