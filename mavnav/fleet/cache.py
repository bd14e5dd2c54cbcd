"""Content-addressed cache of per-file audit results.

A result is stored under a key that hashes everything that decides it
(:func:`cache_key`): the file's bytes (SHA-256), the effective configuration
(its canonical JSON, so two YAML files meaning the same thing share a key),
``--sysid``, the mavnav version plus a fingerprint of the sources that
compute an audit (:func:`code_fingerprint`: an edited estimator is a new
key even without a version bump), and the versions of pymavlink and numpy. Renaming or
moving a file keeps its key; editing one byte of it, of the configuration or
of the estimator changes it.

Layout: ``<cache dir>/v1/<key[:2]>/<key>.json``, one file per result written
atomically (temporary file + rename), so concurrent runs sharing a cache dir
at worst compute a file twice. Failures are not cached.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Optional

SCHEMA = 1
DEFAULT_CACHE_DIR = ".mavnav-cache"
_CHUNK = 1 << 20


def file_sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "?"


# Sources that do not take part in auditing a file: the command line, the
# simulator, the output sinks other than their base, the fleet machinery other
# than the task. Everything else (ingest, estimator, monitor, pipeline, audit,
# config...) is in the fingerprint, including modules added later.
_NOT_AUDIT_DIRS = {"cli", "sim"}
_NOT_AUDIT_FILES = {"covariance.py", "fleet/__init__.py", "fleet/cache.py", "fleet/runner.py",
                    "fleet/report.py"}
_AUDIT_SINKS = {"sinks/__init__.py", "sinks/base.py"}


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 over the mavnav sources that compute an audit (see ``_NOT_AUDIT_*``)."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root).as_posix()
        if rel.split("/")[0] in _NOT_AUDIT_DIRS or rel in _NOT_AUDIT_FILES \
                or (rel.startswith("sinks/") and rel not in _AUDIT_SINKS):
            continue
        h.update(rel.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def environment_key() -> dict:
    from .. import __version__

    return {"mavnav": __version__, "code": code_fingerprint(),
            "pymavlink": _version("pymavlink"), "numpy": _version("numpy")}


def cache_key(file_digest: str, cfg_json: str, sysid: Optional[int], faults: tuple = ()) -> str:
    """The key of one file's result (hex SHA-256); injected faults (specs) are part of it."""
    doc = {"schema": SCHEMA, "file_sha256": file_digest,
           "config_sha256": hashlib.sha256(cfg_json.encode()).hexdigest(),
           "sysid": sysid, **environment_key()}
    if faults:
        doc["faults"] = list(faults)
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


class ResultCache:
    """Per-file results on disk, by :func:`cache_key`."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.dir = self.root / f"v{SCHEMA}"

    def path(self, key: str) -> Path:
        return self.dir / key[:2] / f"{key}.json"

    def get(self, key: str) -> Optional[dict]:
        """The stored result, or None (absent, unreadable or not ours)."""
        try:
            doc = json.loads(self.path(key).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(doc, dict) or doc.get("key") != key or not isinstance(doc.get("result"), dict):
            return None
        return doc["result"]

    def put(self, key: str, result: dict, meta: Optional[dict] = None) -> None:
        if "error" in result:
            return
        result = {k: v for k, v in result.items() if k != "fleet"}
        p = self.path(key)
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=p.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"key": key, "meta": meta or {}, "result": result}, f, default=str)
            os.replace(tmp, p)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise

    def __len__(self) -> int:
        return sum(1 for _ in self.dir.glob("*/*.json")) if self.dir.is_dir() else 0
