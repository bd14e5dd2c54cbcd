"""Run :func:`~mavnav.fleet.task.audit_task` over many files, on one of three backends.

* ``serial``: in this process (``--workers 1``);
* ``processes``: a local pool of ``N`` processes (``concurrent.futures``, no
  extra dependency);
* ``dask``: a Dask distributed cluster at ``scheduler`` (``mavnav[fleet]``).

One file is one task. Before submitting, the client hashes every file and
looks its key up in the :class:`~mavnav.fleet.cache.ResultCache`: hits are
skipped, the rest are submitted, and each result is stored as it arrives.
A task never raises for a bad file; a task that dies with its worker is
reported against its file and the run goes on.
"""

from __future__ import annotations

import json
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Optional, Sequence, TextIO

from ..config import Config, load_config
from ..errors import MavnavError
from .cache import ResultCache, cache_key, file_sha256
from .task import audit_task, config_json, relabel


@dataclass
class FleetCounts:
    total: int = 0
    done: int = 0  # audited in this run
    failed: int = 0  # unreadable / failed task
    skipped: int = 0  # result taken from the cache
    started: float = field(default_factory=time.monotonic)

    @property
    def finished(self) -> int:
        return self.done + self.failed + self.skipped

    def line(self) -> str:
        el = time.monotonic() - self.started
        rate = (self.done + self.failed) / el if el > 0 else 0.0
        return (f"fleet: {self.finished}/{self.total} files: {self.done} done, {self.failed} failed, "
                f"{self.skipped} skipped (cached), {rate:.2f} files/s, {el:.0f} s")


class Progress:
    """Progress of the whole fleet on stderr: a rewritten line on a terminal,
    otherwise one line every ``every_s`` seconds and a last one at the end."""

    def __init__(self, stream: Optional[TextIO] = None, every_s: float = 5.0) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.every_s = every_s
        self._last = time.monotonic()
        self._shown: Optional[tuple] = None

    def __call__(self, c: FleetCounts, final: bool = False) -> None:
        now = time.monotonic()
        state = (c.done, c.failed, c.skipped)
        if self.tty:
            self.stream.write("\r" + c.line() + ("\n" if final else ""))
        elif (final and state != self._shown) or now - self._last >= self.every_s:
            self.stream.write(c.line() + "\n")
            self._last = now
            self._shown = state
        else:
            return
        self.stream.flush()


def _normal(result: dict) -> dict:
    """What ``--json`` writes: cached and fresh results are then identical."""
    return json.loads(json.dumps(result, default=str))


def _hash_all(paths: Sequence[str], threads: int = 4) -> list[Optional[str]]:
    def one(p: str) -> Optional[str]:
        try:
            return file_sha256(p)
        except OSError:
            return None  # the task reports why
    if len(paths) < 2:
        return [one(p) for p in paths]
    with ThreadPoolExecutor(max_workers=threads) as ex:
        return list(ex.map(one, paths))


# ---------------------------------------------------------------- backends
# Each yields (index, result) as tasks finish; jobs are (index, args of audit_task).


def _run_serial(jobs) -> Iterator[tuple[int, dict]]:
    for i, args in jobs:
        yield i, audit_task(*args)


def _preload() -> None:  # runs in each pool process
    import signal

    import mavnav.audit  # noqa: F401

    # Ctrl-C reaches the whole process group: the parent handles it (and
    # terminates the pool); a worker would only print a traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _largest_first(jobs) -> list:
    """The jobs by file size, largest first (ties in input order): the long
    audits start early instead of one worker finishing the fleet's last big
    file alone. Results still go back to their input places."""

    def size(job) -> int:
        try:
            return os.path.getsize(job[1][0])
        except OSError:
            return 0

    return sorted(jobs, key=lambda job: -size(job))


def _run_processes(jobs, workers: int) -> Iterator[tuple[int, dict]]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    methods = multiprocessing.get_all_start_methods()
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["mavnav.fleet.task"])  # import once, fork per worker
    else:
        ctx = multiprocessing.get_context("spawn")
    from concurrent.futures.process import BrokenProcessPool

    # A worker that dies (crash, OOM kill) breaks the whole pool and every
    # task in flight with it: the unfinished ones go to a new pool, once.
    attempts: dict[int, int] = {}
    todo = _largest_first(jobs)
    while todo:
        retry = []
        ex = ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=ctx, initializer=_preload)
        try:
            futs = {ex.submit(audit_task, *args): (i, args) for i, args in todo}
            pending = set(futs)
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    i, args = futs[f]
                    if isinstance(f.exception(), BrokenProcessPool) and attempts.get(i, 0) < 1:
                        attempts[i] = attempts.get(i, 0) + 1
                        retry.append((i, args))
                        continue
                    yield i, _outcome(f, args)
        except BaseException:  # Ctrl-C, or the caller stopped: stop the workers, drop the rest
            for proc in list((getattr(ex, "_processes", None) or {}).values()):
                proc.terminate()
            ex.shutdown(wait=False, cancel_futures=True)
            raise
        ex.shutdown(wait=True)
        todo = retry


def _outcome(fut, args) -> dict:
    """A future's result, or the reason it has none, against its file."""
    try:
        return fut.result()
    except Exception as exc:  # worker died, killed task, lost connection
        return {"path": args[1], "error": f"task failed: {type(exc).__name__}: {exc}".rstrip(": ")}


SCHEDULER_TIMEOUT = "10s"  # to connect to --scheduler


def dask_client(scheduler):
    """A ``distributed.Client`` for an address (or the client itself); one-line errors."""
    try:
        import distributed
    except ImportError:
        raise MavnavError("--scheduler needs Dask distributed: pip install 'mavnav[fleet]'") from None
    if isinstance(scheduler, distributed.Client):
        return scheduler, False
    try:
        return distributed.Client(scheduler, timeout=SCHEDULER_TIMEOUT, set_as_default=False), True
    except (OSError, TimeoutError) as exc:
        raise MavnavError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None


def _run_dask(jobs, scheduler) -> Iterator[tuple[int, dict]]:
    import distributed

    client, own = dask_client(scheduler)
    try:
        futs = {}
        for i, args in jobs:
            # One task per file; pure=False: the key must not depend on the
            # arguments only (a rerun with --rerun must recompute).
            f = client.submit(audit_task, *args, key=f"mavnav-audit-{i}-{os.urandom(4).hex()}", pure=False)
            futs[f] = (i, args)
        for f in distributed.as_completed(list(futs), loop=client.loop):
            i, args = futs.pop(f)
            out = _outcome(f, args)
            f.release()
            yield i, out
    finally:
        if own:
            client.close()


# ---------------------------------------------------------------- the run


@dataclass
class FleetRun:
    results: list[dict]
    counts: FleetCounts
    elapsed_s: float
    backend: str


def _dispatch(jobs: list, backend: Optional[str], scheduler, workers: int) -> tuple[str, Iterator]:
    """The backend that runs the jobs (named, or chosen: Dask with a scheduler,
    processes for more than one worker and job, else serial) and its results."""
    if backend is None:
        backend = "dask" if scheduler is not None else "processes" if workers > 1 and len(jobs) > 1 else "serial"
    if not jobs:
        return "cache", iter(())
    if backend == "dask":
        return backend, _run_dask(jobs, scheduler)
    if backend == "processes":
        return backend, _run_processes(jobs, min(workers, len(jobs)))
    if backend == "serial":
        return backend, _run_serial(jobs)
    raise ValueError(f"unknown backend {backend!r}")


def _cache_put(cache: Optional[ResultCache], key: Optional[str], r: dict, digest: Optional[str]) -> None:
    if cache is None or key is None:
        return
    try:
        cache.put(key, r, meta={"path": r["path"], "sha256": digest})
    except OSError as exc:
        raise MavnavError(f"cannot write the cache in {cache.root}: {exc.strerror or exc}") from None


def run_fleet(files: Sequence[str | Path], cfg: Config, *, sysid: Optional[int] = None, workers: int = 1,
              scheduler=None, cache_dir: Optional[str | Path] = None, rerun: bool = False,
              progress: Optional[Callable[[FleetCounts, bool], None]] = None,
              backend: Optional[str] = None, faults: Sequence[str] = ()) -> FleetRun:
    """Audit ``files``; results in input order, each with ``result["fleet"]``
    (``sha256``, ``cached``, ``elapsed_s``, ``worker``...).

    ``cache_dir=None`` disables the cache; ``rerun=True`` recomputes every
    file and overwrites its entry. ``backend`` forces ``"serial"`` or
    ``"processes"`` (default: Dask with a scheduler, processes for more than
    one worker and file, else serial). ``faults`` (``mavnav inject`` specs)
    are injected into every file's samples.
    """
    faults = tuple(faults)
    t0 = time.monotonic()
    displays = [str(f) for f in files]
    abspaths = [os.path.abspath(f) for f in files]
    cjson = config_json(cfg)
    counts = FleetCounts(total=len(files))
    cache = ResultCache(cache_dir) if cache_dir is not None else None
    digests = _hash_all(abspaths) if cache is not None or scheduler is not None else [None] * len(files)
    keys = [cache_key(d, cjson, sysid, faults) if d is not None else None for d in digests]
    results: list[Optional[dict]] = [None] * len(files)
    report = progress or (lambda c, final=False: None)

    jobs = []
    for i, (disp, ap, key) in enumerate(zip(displays, abspaths, keys)):
        hit = cache.get(key) if (cache is not None and key is not None and not rerun) else None
        if hit is not None:
            r = relabel(hit, disp)
            r["fleet"] = {"sha256": digests[i], "key": key, "cached": True}
            results[i] = r
            counts.skipped += 1
        else:
            jobs.append((i, (ap, disp, cjson, sysid, faults)))
    report(counts, False)

    backend, it = _dispatch(jobs, backend, scheduler, workers)
    for i, r in it:
        r = _normal(r)
        info = r.setdefault("fleet", {})
        info.update(sha256=digests[i], key=keys[i], cached=False)
        if "error" in r:
            counts.failed += 1
        else:
            counts.done += 1
            _cache_put(cache, keys[i], r, digests[i])
        results[i] = r
        report(counts, False)
    report(counts, True)
    return FleetRun(results=[r for r in results if r is not None], counts=counts,
                    elapsed_s=time.monotonic() - t0, backend=backend)


def audit_parallel(files: Sequence[str | Path], config_path=None, sysid: Optional[int] = None, workers: int = 2,
                   scheduler=None, cache_dir=None, rerun: bool = False, progress=None) -> list[dict]:
    """Per-file results in input order (an unreadable file as ``{"path", "error"}``)."""
    cfg = load_config(config_path)
    return run_fleet(files, cfg, sysid=sysid, workers=workers, scheduler=scheduler, cache_dir=cache_dir,
                     rerun=rerun, progress=progress).results
