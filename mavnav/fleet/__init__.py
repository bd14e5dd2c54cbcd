"""Fleet audit: many tlogs, one task per file, in parallel or on a Dask cluster.

``mavnav audit PATH... --workers N`` uses a local process pool;
``--scheduler ADDRESS`` submits the same task to a Dask distributed cluster
(``pip install 'mavnav[fleet]'``). Results are cached by content
(:mod:`mavnav.fleet.cache`) and summarised for the fleet as Parquet tables
and a Markdown report with plots (:mod:`mavnav.fleet.report`).

Nothing here imports dask, pyarrow or matplotlib until it is used, nor the
audit itself (``runner``, ``task``: the estimator, numba, scipy) until one of
their names is first read: the CLI reads ``DEFAULT_CACHE_DIR`` for its help.
"""

from importlib import import_module

from .cache import DEFAULT_CACHE_DIR, ResultCache, cache_key, file_sha256

_LAZY = {name: "runner" for name in ("FleetCounts", "FleetRun", "Progress", "audit_parallel", "run_fleet")}
_LAZY.update({name: "task" for name in ("audit_one", "audit_task", "config_json")})


def __getattr__(name: str):
    """The names of ``runner`` and ``task``, imported when first used (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


__all__ = ["audit_parallel", "run_fleet", "FleetRun", "FleetCounts", "Progress", "ResultCache", "cache_key",
           "file_sha256", "audit_task", "audit_one", "config_json", "DEFAULT_CACHE_DIR"]
