"""Fleet audit: many tlogs, one task per file, in parallel or on a Dask cluster.

``mavnav audit PATH... --workers N`` uses a local process pool;
``--scheduler ADDRESS`` submits the same task to a Dask distributed cluster
(``pip install 'mavnav[fleet]'``). Results are cached by content
(:mod:`mavnav.fleet.cache`) and summarised for the fleet as Parquet tables
and a Markdown report with plots (:mod:`mavnav.fleet.report`).

Nothing here imports dask, pyarrow or matplotlib until it is used.
"""

from .cache import DEFAULT_CACHE_DIR, ResultCache, cache_key, file_sha256
from .runner import FleetCounts, FleetRun, Progress, audit_parallel, run_fleet
from .task import audit_one, audit_task, config_json

__all__ = ["audit_parallel", "run_fleet", "FleetRun", "FleetCounts", "Progress", "ResultCache", "cache_key",
           "file_sha256", "audit_task", "audit_one", "config_json", "DEFAULT_CACHE_DIR"]
