"""The one task of a fleet audit: one file in, one JSON-ready dict out.

The same function runs in this process (``--workers 1``), in a local process
pool (``--workers N``) and on Dask workers (``--scheduler``). It takes only
plain, picklable arguments (paths as strings, the configuration as the JSON
dict of its fields) so a worker on another machine needs nothing but mavnav
and read access to the file.
"""

from __future__ import annotations

import functools
import json
import os
import socket
import time
import traceback
from pathlib import Path
from typing import Iterable, Optional, Sequence

from ..audit import audit_file
from ..config import Config, config_from_dict
from ..errors import MavnavError
from ..sinks.base import Sink


def relabel(result: dict, display: str) -> dict:
    """Name a result after the path as the user gave it (not the absolute or cached one)."""
    old = result.get("path")
    result["path"] = display
    ingest = result.get("ingest")
    if isinstance(ingest, dict) and ingest.get("source") == old:
        ingest["source"] = display
    return result


def audit_one(path: str | Path, cfg: Config, sysid: Optional[int] = None,
              extra_sinks: Iterable[Sink] = (), display: Optional[str] = None, faults: Sequence = ()) -> dict:
    """Audit one file; an unreadable one gives ``{"path", "error"}`` instead of raising."""
    display = str(path) if display is None else display
    try:
        result = audit_file(path, cfg, sysid=sysid, extra_sinks=extra_sinks, faults=faults)
    except MavnavError as exc:
        return {"path": display, "error": str(exc)}
    return relabel(result, display)


@functools.lru_cache(maxsize=8)
def _config(cfg_json: str) -> Config:
    return config_from_dict(json.loads(cfg_json), origin="<fleet config>")


def config_json(cfg: Config) -> str:
    """The canonical JSON text of a configuration: what tasks receive and what the cache key hashes.
    Without the keys that only say how results are shown or sent (``OUTPUT_ONLY_KEYS``):
    an audit does not depend on them."""
    from ..config import OUTPUT_ONLY_KEYS

    return json.dumps(cfg.model_dump(mode="json", exclude=OUTPUT_ONLY_KEYS), sort_keys=True, separators=(",", ":"))


def audit_task(path: str, display: str, cfg_json: str, sysid: Optional[int] = None, faults: tuple = ()) -> dict:
    """The fleet task. Never raises for a bad file: any failure becomes ``{"path", "error"}``.

    ``result["fleet"]`` carries what legitimately differs between runs
    (elapsed and CPU time, which worker); the rest is exactly :func:`audit_file`'s dict.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    info: dict = {"worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        result = audit_one(path, _config(cfg_json), sysid=sysid, display=display, faults=faults)
    except Exception as exc:  # a bug must not stop the fleet: report it against the file
        result = {"path": display, "error": f"internal error: {type(exc).__name__}: {exc}"}
        info["traceback"] = traceback.format_exc(limit=20)
    info["elapsed_s"] = round(time.perf_counter() - t0, 4)
    info["cpu_s"] = round(time.process_time() - c0, 4)
    result["fleet"] = info
    return result
