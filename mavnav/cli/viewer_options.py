"""Rerun viewer options for the run, replay and audit commands.

``@viewer_options`` adds::

    --viewer [spawn|web|none]  spawn a native viewer, serve a web viewer, or none (default)
    --connect URL              also stream to a running viewer (rerun+http://HOST:PORT/proxy, or a port)
    --rrd FILE                 also save the recording to FILE
    --web-port / --grpc-port   ports of the web viewer and of its data (gRPC) server;
                               --grpc-port is also the spawned viewer's port
    --viewer-bind ADDR         address they listen on (default 127.0.0.1)
    --viewer-window SECONDS    live runs: the views show the last SECONDS of vehicle time
    --viewer-hold/--no-viewer-hold
                               web viewer: keep serving after the run until Ctrl-C (default)

each also a key of the configuration's ``viewer:`` section; a flag given on
the command line wins over the key. The command receives the flags given as
one dict, ``viewer_flags``, and builds the sinks from the two::

    viewer = viewer_settings(cfg, viewer_flags)
    sinks += viewer_sinks(viewer, live=...)

Web mode runs ``rerun --serve-web`` (from rerun-sdk) as a child process that
hosts both the viewer page and its data, bound to ``--viewer-bind``; the page
URL is printed on stderr. The child is stopped when mavnav exits; when held
(and stdin is a terminal) mavnav first waits for Ctrl-C, so a replay can be
looked at after it ends. Busy ports are replaced by free ones (and said so).
A spawned native viewer (``rerun --port GRPC_PORT``, reused if one already
listens there) is the user's window: it is left running. Viewer trouble
(cannot start, no display, nothing listening at ``--connect``, goes away
mid-run) is reported and never stops the monitor; the ``.rrd`` is written
regardless.
"""

from __future__ import annotations

import atexit
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional
from urllib.parse import quote, urlsplit

import click

from ..errors import MavnavError
from .flags import flag_group

if TYPE_CHECKING:
    from ..config import Config, ViewerSection

log = logging.getLogger("mavnav.cli.viewer")

VIEWERS = ("spawn", "web", "none")
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876
START_TIMEOUT_S = 15.0


#: click parameter -> key of the configuration's ``viewer:`` section
VIEWER_FLAGS = {"viewer": "viewer", "connect": "connect", "rrd": "rrd", "web_port": "web_port",
                "grpc_port": "grpc_port", "viewer_bind": "bind", "viewer_window": "window_s", "viewer_hold": "hold"}


def viewer_options(f: Callable) -> Callable:
    """Add the Rerun viewer options to a click command, which receives those
    given on the command line as one dict, ``viewer_flags``."""
    options = [
        click.option("--viewer", type=click.Choice(VIEWERS), default="none", show_default=True,
                     help="Show the run in Rerun: spawn a native viewer, or serve a web viewer."),
        click.option("--connect", "connect", metavar="URL", default=None,
                     help="Also stream to a running Rerun viewer or server (rerun+http://HOST:PORT/proxy, or a port)."),
        click.option("--rrd", "rrd", type=click.Path(dir_okay=False, writable=True), default=None,
                     help="Also save the Rerun recording to this .rrd file."),
        click.option("--web-port", type=click.IntRange(0, 65535), default=DEFAULT_WEB_PORT, show_default=True,
                     help="Port of the web viewer page (--viewer web; 0: any free port)."),
        click.option("--grpc-port", type=click.IntRange(0, 65535), default=DEFAULT_GRPC_PORT, show_default=True,
                     help="Port of the viewer's data server (--viewer web or spawn; 0: any free port)."),
        click.option("--viewer-bind", default="127.0.0.1", show_default=True, metavar="ADDR",
                     help="Address the web viewer and its data server listen on."),
        click.option("--viewer-window", type=click.FloatRange(min=0.0, min_open=True), default=30.0,
                     show_default=True, metavar="SECONDS",
                     help="Live runs: seconds of vehicle time the views show, up to the cursor."),
        click.option("--viewer-hold/--no-viewer-hold", default=True, show_default=True,
                     help="--viewer web: keep serving after the run ends, until Ctrl-C."),
    ]
    return flag_group(options, tuple(VIEWER_FLAGS), "viewer_flags")(f)


def viewer_settings(cfg: Config, flags: dict) -> ViewerSection:
    """The configuration's ``viewer:`` section with the flags given over it."""
    from ..config import with_overrides

    return with_overrides(cfg.viewer, {VIEWER_FLAGS[k]: v for k, v in flags.items()}, "viewer options")


def viewer_sinks(viewer: ViewerSection, live: bool) -> list:
    """:func:`make_viewer_sinks` for these settings."""
    return make_viewer_sinks(viewer.viewer, viewer.connect, viewer.rrd, live=live, web_port=viewer.web_port,
                             grpc_port=viewer.grpc_port, viewer_bind=viewer.bind, viewer_window=viewer.window_s,
                             viewer_hold=viewer.hold)


# --------------------------------------------------------------------------
# Helpers


def rerun_executable() -> str:
    """The ``rerun`` program installed with rerun-sdk: the binary itself, not
    the Python wrapper script (which would run it as a grandchild)."""
    try:
        import rerun_cli

        binary = Path(rerun_cli.__file__).parent / ("rerun.exe" if sys.platform.startswith("win") else "rerun")
        if binary.is_file():
            return str(binary)
    except ImportError:
        pass
    here = Path(sys.executable).parent / "rerun"
    if here.exists():
        return str(here)
    found = shutil.which("rerun")
    if found is None:
        raise MavnavError("the 'rerun' program of rerun-sdk is not installed")
    return found


def port_open(host: str, port: int, timeout_s: float = 0.3) -> bool:
    """Whether something accepts TCP connections at host:port."""
    try:
        with socket.create_connection((_connect_host(host), port), timeout=timeout_s):
            return True
    except OSError:
        return False


def _connect_host(host: str) -> str:
    return "127.0.0.1" if host in ("0.0.0.0", "") else ("::1" if host == "::" else host)


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def grpc_url(connect: str) -> tuple[str, str, int]:
    """Normalise ``--connect``: a port, HOST:PORT, or a rerun URL -> (url, host, port)."""
    text = connect.strip()
    if text.isdigit():
        text = f"rerun+http://127.0.0.1:{int(text)}/proxy"
    elif "://" not in text:
        text = f"rerun+http://{text}/proxy"
    parts = urlsplit(text)
    if parts.scheme not in ("rerun", "rerun+http", "rerun+https") or parts.path != "/proxy" or not parts.hostname:
        raise MavnavError(f"--connect {connect!r}: expected rerun+http://HOST:PORT/proxy or a port")
    try:
        port = parts.port
    except ValueError:
        raise MavnavError(f"--connect {connect!r}: bad port") from None
    if port is None:
        port = 443 if parts.scheme == "rerun+https" else DEFAULT_GRPC_PORT
    return text, parts.hostname, port


def web_page_url(host: str, web_port: int, data_url: str) -> str:
    """The page to open: the web viewer, told where its data is (WebGL renderer)."""
    return f"http://{_connect_host(host)}:{web_port}/?renderer=webgl&url={quote(data_url, safe='')}"


def _tcp_check(host: str, port: int) -> Callable[[], Optional[str]]:
    def check() -> Optional[str]:
        return None if port_open(host, port) else f"nothing listens on {host}:{port} any more"

    return check


class ViewerProcess:
    """A ``rerun`` child process (web server or native viewer) and its ports."""

    def __init__(self, args: list[str], host: str, ports: tuple[int, ...]):
        self._log = tempfile.NamedTemporaryFile(prefix="mavnav-rerun-", suffix=".log", delete=False)
        self.args = args
        self.host, self.ports = host, ports
        self.port = ports[0]  # the data (gRPC) port
        self.proc = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # Ctrl-C in the terminal reaches mavnav, which stops us in order
        )

    def wait_ready(self, timeout_s: float = START_TIMEOUT_S, settle_s: float = 0.0) -> Optional[str]:
        """None once the ports accept connections (and the process is still
        up ``settle_s`` later), else why not."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                return f"the viewer exited with status {self.proc.returncode}: {self.tail()}"
            if all(port_open(self.host, p, 0.2) for p in self.ports):
                if settle_s > 0:
                    time.sleep(settle_s)
                    if self.proc.poll() is not None:
                        return f"the viewer exited with status {self.proc.returncode}: {self.tail()}"
                return None
            time.sleep(0.1)
        return f"the viewer did not listen on ports {self.ports} within {timeout_s:.0f} s"

    def tail(self, n: int = 2) -> str:
        try:
            lines = Path(self._log.name).read_text(errors="replace").strip().splitlines()
        except OSError:
            return ""
        return " | ".join(line.strip() for line in lines[-n:])

    def check(self) -> Optional[str]:
        code = self.proc.poll()
        if code is not None:
            return f"the viewer process exited with status {code}"
        if not port_open(self.host, self.port):
            return f"nothing listens on {self.host}:{self.port} any more"
        return None

    def stop(self) -> None:
        """Stop the child and anything it started (its own process group)."""
        if self.proc.poll() is None:
            self._signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._signal(signal.SIGKILL)
                self.proc.wait()

    def _signal(self, sig: int) -> None:
        try:
            os.killpg(self.proc.pid, sig)  # start_new_session: the group is the child's own
        except (ProcessLookupError, PermissionError, AttributeError):
            self.proc.send_signal(sig)
        try:
            self._log.close()
            os.unlink(self._log.name)
        except OSError:
            pass


def _hold(url: str, process: ViewerProcess, echo: Callable[[str], None]) -> None:
    """At exit: keep the web viewer serving until Ctrl-C (only on a terminal)."""
    if process.proc.poll() is not None:
        return
    if not sys.stdin or not sys.stdin.isatty():
        echo("mavnav: not waiting for the web viewer (no terminal); it stops now")
        return
    echo(f"mavnav: the run is over; the web viewer keeps serving at {url} - press Ctrl-C to stop it")
    try:
        while process.proc.poll() is None:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass


# --------------------------------------------------------------------------
# The factory


def _echo_err(text: str) -> None:
    click.echo(text, err=True)


def make_viewer_sinks(
    viewer: str = "none",
    connect: Optional[str] = None,
    rrd: Optional[str] = None,
    live: bool = False,
    *,
    web_port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    viewer_bind: str = "127.0.0.1",
    viewer_window: float = 30.0,
    viewer_hold: bool = True,
    echo: Callable[[str], None] = _echo_err,
    application_id: str = "mavnav",
    live_batch_s: float = 0.25,
) -> list:
    """The sinks the viewer options ask for: ``[]`` or one :class:`RerunSink`.

    ``live`` picks small batches (every ``live_batch_s`` of vehicle time; 0:
    row by row) and a cursor-relative time window; replays send columns in
    bulk. Messages for the user (the web viewer's
    URL, a viewer that cannot start) go to ``echo`` (stderr by default).
    The returned sink has ``.page_url`` (web mode, else None) and
    ``.processes`` (the rerun children it started).
    """
    import rerun as rr

    if viewer not in VIEWERS:
        raise MavnavError(f"--viewer {viewer!r}: expected one of {', '.join(VIEWERS)}")
    if viewer == "none" and not connect and not rrd:
        return []
    found = _Targets()
    if viewer == "web":
        _add_web_viewer(found, rr, viewer_bind, web_port, grpc_port, viewer_hold, echo)
    elif viewer == "spawn":
        _add_spawned_viewer(found, rr, viewer_bind, grpc_port, echo)
    if connect:
        _add_connected_viewer(found, rr, connect, echo)
    if rrd:
        found.targets.append((rr.FileSink(str(rrd)), None))
    if not found.targets:
        return []
    return [_rerun_sink(found, rr, application_id, live, viewer_window, live_batch_s)]


@dataclass
class _Targets:
    """What :func:`make_viewer_sinks` found to send to, and what it started."""

    targets: list = field(default_factory=list)  # (rerun sink, ViewerTarget or None: what to watch)
    processes: list = field(default_factory=list)  # ViewerProcess children started
    on_close: list = field(default_factory=list)  # called when the sink closes
    page_url: Optional[str] = None  # the web viewer's page
    grpc_urls: set = field(default_factory=set)  # data servers already targeted


def _pick_port(port: int, what: str, bind: str, echo: Callable[[str], None]) -> int:
    """``port``, or a free one when it is 0 or busy (said so)."""
    if port == 0:
        return free_port(bind)
    if port_open(bind, port):
        chosen = free_port(bind)
        echo(f"mavnav: port {port} ({what}) is busy; using {chosen}")
        return chosen
    return port


def _add_web_viewer(found: _Targets, rr, bind: str, web_port: int, grpc_port: int, hold: bool,
                    echo: Callable[[str], None]) -> None:
    """Start ``rerun --serve-web`` and target it (or say why not)."""
    from ..sinks.rerun_sink import ViewerTarget

    gport = _pick_port(grpc_port, "viewer data", bind, echo)
    wport = _pick_port(web_port, "web viewer", bind, echo)
    args = [rerun_executable(), "--serve-web", "--bind", bind, "--port", str(gport),
            "--web-viewer-port", str(wport)]
    process = ViewerProcess(args, bind, (gport, wport))
    why = process.wait_ready()
    if why is not None:
        process.stop()
        echo(f"mavnav: warning: the web viewer could not start ({why}); going on without it")
        return
    data_url = f"rerun+http://{_connect_host(bind)}:{gport}/proxy"
    page_url = web_page_url(bind, wport, data_url)
    found.page_url = page_url
    found.processes.append(process)
    found.grpc_urls.add(data_url)
    found.targets.append((rr.GrpcSink(data_url), ViewerTarget(f"the web viewer ({page_url})", process.check)))
    atexit.register(process.stop)
    if hold:
        # registered after stop(): atexit runs it first
        found.on_close.append(lambda: atexit.register(_hold, page_url, process, echo))
    echo(f"mavnav: Rerun web viewer at {page_url}")


def _no_display() -> bool:
    return sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _add_spawned_viewer(found: _Targets, rr, bind: str, grpc_port: int, echo: Callable[[str], None]) -> None:
    """Target the native viewer at the gRPC port, spawned unless one already
    listens there (or say why not)."""
    from ..sinks.rerun_sink import ViewerTarget

    gport = DEFAULT_GRPC_PORT if grpc_port == 0 else grpc_port
    data_url = f"rerun+http://{_connect_host(bind)}:{gport}/proxy"
    why: Optional[str] = None
    if port_open(bind, gport):
        pass  # a viewer is already there: use it, as rerun's own spawn does
    elif _no_display():
        why = "no display (DISPLAY and WAYLAND_DISPLAY are unset); try --viewer web"
    else:
        args = [rerun_executable(), "--bind", bind, "--port", str(gport), "--memory-limit", "75%"]
        process = ViewerProcess(args, bind, (gport,))
        why = process.wait_ready(settle_s=1.0)  # it listens before it opens its window
        if why is not None:
            process.stop()
    if why is not None:
        echo(f"mavnav: warning: the Rerun viewer could not start ({why}); going on without it")
        return
    found.grpc_urls.add(data_url)
    found.targets.append((rr.GrpcSink(data_url),
                          ViewerTarget(f"the Rerun viewer at {data_url}", _tcp_check(bind, gport))))


def _add_connected_viewer(found: _Targets, rr, connect: str, echo: Callable[[str], None]) -> None:
    """Target the viewer at ``--connect`` if one listens there (and it is not targeted already)."""
    from ..sinks.rerun_sink import ViewerTarget

    url, host, port = grpc_url(connect)
    if url in found.grpc_urls:
        return
    if not port_open(host, port, 1.0):
        # rerun would block for seconds trying to connect: do not attach at all
        echo(f"mavnav: warning: no Rerun viewer listens at {url}; going on without it")
        return
    found.targets.append((rr.GrpcSink(url), ViewerTarget(f"the Rerun viewer at {url}", _tcp_check(host, port))))


def _rerun_sink(found: _Targets, rr, application_id: str, live: bool, window_s: float, live_batch_s: float):
    """One :class:`RerunSink` over one recording stream that sends to every target (Rerun's ``set_sinks``)."""
    import uuid

    from ..sinks.rerun_sink import RerunSink

    rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
    rec.set_sinks(*(rr_sink for rr_sink, _ in found.targets))
    watched = [target for _, target in found.targets if target is not None]
    has_file = any(target is None for _, target in found.targets)
    sink = RerunSink(rec, live=live, targets=watched, has_file=has_file, window_s=window_s,
                     live_batch_s=live_batch_s, on_close=found.on_close)
    sink.page_url = found.page_url  # type: ignore[attr-defined]
    sink.processes = found.processes  # type: ignore[attr-defined]
    return sink


__all__ = ["viewer_options", "viewer_settings", "viewer_sinks", "VIEWER_FLAGS", "make_viewer_sinks", "grpc_url", "web_page_url", "port_open", "free_port",
           "rerun_executable", "ViewerProcess"]
