"""Golden outputs of ``mavnav audit`` and of the MAVLink output of ``mavnav
replay`` over the real and SITL logs, and a byte comparison of two such
sets: the safety net of a refactoring that must not change behaviour.

    # write the outputs of the code on PYTHONPATH (or installed) into DIR
    python bench/golden.py run DIR [--more]
    # compare two output directories file by file, byte for byte
    python bench/golden.py compare BEFORE AFTER

``run`` audits each log in its own ``mavnav audit`` process with
``--json``, ``--csv`` and the printed table, and keeps, per log
``NAME.json``, ``NAME.csv``, ``NAME.stdout``, ``NAME.stderr`` and
``NAME.rc`` (the exit status). It then replays the log in its own
``mavnav replay LOG --speed max --emit TTY --emit-debug --emit-fusable``
process and keeps the MAVLink output, every frame mavnav sent (HEARTBEAT,
ALTITUDE, STATUSTEXT, NAMED_VALUE_FLOAT, ODOMETRY), as the raw bytes on
the wire, ``NAME.mavlink``, and the replay's exit status, ``NAME.replay.rc``
(``compare`` says where two ``.mavlink`` files first differ, decoded).
The logs: every ``.tlog`` in
``../shared/tlogs/real`` and ``../shared/tlogs/other``, every
``.tlog``/``.bin``/``.BIN``/``.ulg`` in ``../shared/flightlogs``, and the
repository's ``sitl_logs/*.tlog``; ``--more`` adds
``~/.cache/mavnav-flightlogs``. The logs are read where they are, never
copied.

Nothing is normalised: the outputs hold the log's absolute path (the same
in both runs) and no wall-clock time. The code audited is the ``mavnav``
that PYTHONPATH (else the installation) names, said on stderr: each audit
and replay runs in the output directory, so that no working directory
shadows it. ``compare`` exits 1 when a file differs or is missing on one
side.

The MAVLink capture. ``--emit`` takes a pymavlink connection string, which
offers no file to write to (and a UDP socket could drop datagrams when its
receive buffer fills under load, without pymavlink saying so); ``TTY`` is
the slave side of a pseudo-terminal that ``run`` opens in raw mode and
reads from its master side in a thread. pymavlink writes to it as to a
serial device, with blocking writes (pyserial, no write timeout): a full
pty buffer stalls the replay until the reader catches up, so nothing is
dropped, reordered or altered. The end is known without waiting on a
clock: once the replay has exited, ``run`` writes a marker into the slave
side, which arrives behind every byte the replay wrote. The bytes are
deterministic, hence kept raw: every time in them is the log's vehicle time
(ALTITUDE/ODOMETRY ``time_usec``, NAMED_VALUE_FLOAT ``time_boot_ms``, the
HEARTBEAT and ALTITUDE grids), the sequence number counts frames, and
nothing from the wall clock is sent: no ``--signing-key`` (a signature's
timestamp starts from the wall clock) and no ``--allow-commands`` (paced by
the monotonic clock, and nothing answers). The pty's name is not in any
output. The replay runs the whole pipeline again: ``run`` takes about twice
as long as the audits alone (23 logs: 50 s of audits, 50 s of replays),
both said on stderr.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import pty
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"  # beside the repository, read in place
SUFFIXES = {".tlog", ".bin", ".BIN", ".ulg"}
#: What the replay sends besides HEARTBEAT, ALTITUDE and STATUSTEXT: all the
#: MAVLink output there is without a signing key or commands.
EMIT_FLAGS = ("--emit-debug", "--emit-fusable")
#: Written into the pty after the replay has exited: the end of the capture.
_END = b"\n-- end of bench/golden.py's MAVLink capture --\n"


def log_files(more: bool = False) -> list[Path]:
    """The logs of the golden set, in a fixed order."""
    dirs = [(SHARED / "tlogs" / "real", {".tlog"}),
            (SHARED / "tlogs" / "other", {".tlog"}),
            (SHARED / "flightlogs", SUFFIXES),
            (REPO / "sitl_logs", {".tlog"})]
    if more:
        dirs.append((Path.home() / ".cache" / "mavnav-flightlogs", SUFFIXES))
    out: list[Path] = []
    for d, suffixes in dirs:
        if d.is_dir():
            out += sorted(p for p in d.iterdir() if p.is_file() and p.suffix in suffixes)
    return out


def output_stem(path: Path) -> str:
    """One log's output name: its parent folder and file name, flattened."""
    return f"{path.parent.name}__{path.name}"


def mavlink_capture(log: Path, cwd: Path) -> tuple[bytes, int, bytes]:
    """The MAVLink output of ``mavnav replay LOG --speed max`` with ``--emit``
    on the slave side of a pseudo-terminal (see the module docstring): the
    raw bytes sent, the replay's exit status and its stderr."""
    master, slave = pty.openpty()
    try:
        tty.setraw(slave)  # no output processing: bytes pass unchanged
        buf = bytearray()
        exited = threading.Event()

        def read() -> None:
            while True:
                try:
                    chunk = os.read(master, 1 << 16)
                except OSError:  # not expected: this process keeps the slave open
                    return
                buf.extend(chunk)
                if exited.is_set() and buf.endswith(_END):
                    return

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        cmd = [sys.executable, "-m", "mavnav.cli", "replay", str(log), "--speed", "max",
               "--emit", os.ttyname(slave), *EMIT_FLAGS]
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=os.environ.copy(),
                              cwd=cwd)
        exited.set()
        os.write(slave, _END)  # behind every byte the replay wrote
        reader.join()
        if not buf.endswith(_END):
            raise RuntimeError(f"{log}: the MAVLink capture ended without its end marker")
        return bytes(buf[:-len(_END)]), proc.returncode, proc.stderr
    finally:
        os.close(master)
        os.close(slave)


def run(outdir: Path, more: bool) -> int:
    outdir = outdir.resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    logs = log_files(more)
    probe = subprocess.run([sys.executable, "-c", "import mavnav; print(mavnav.__file__)"], capture_output=True,
                           text=True, env=os.environ.copy(), cwd=outdir)
    print(f"mavnav from {probe.stdout.strip()}", file=sys.stderr)
    spent = {"audit": 0.0, "replay": 0.0}
    for i, log in enumerate(logs, 1):
        stem = outdir / output_stem(log)
        cmd = [sys.executable, "-m", "mavnav.cli", "audit", str(log),
               "--json", f"{stem}.json", "--csv", f"{stem}.csv"]
        # run from the output directory: a working directory holding a mavnav
        # package would shadow the one PYTHONPATH (or the installation) names
        t0 = time.monotonic()
        proc = subprocess.run(cmd, capture_output=True, env=os.environ.copy(), cwd=outdir)
        t1 = time.monotonic()
        Path(f"{stem}.stdout").write_bytes(proc.stdout)
        Path(f"{stem}.stderr").write_bytes(proc.stderr)
        Path(f"{stem}.rc").write_text(f"{proc.returncode}\n")
        frames, rc, err = mavlink_capture(log, outdir)
        t2 = time.monotonic()
        Path(f"{stem}.mavlink").write_bytes(frames)
        Path(f"{stem}.replay.rc").write_text(f"{rc}\n")
        spent["audit"] += t1 - t0
        spent["replay"] += t2 - t1
        print(f"[{i}/{len(logs)}] {log} -> rc {proc.returncode} ({t1 - t0:.1f} s), "
              f"replay rc {rc}, {len(frames)} MAVLink bytes ({t2 - t1:.1f} s)", file=sys.stderr)
        if rc != 0:
            print(err.decode(errors="replace").rstrip()[-2000:], file=sys.stderr)
    print(f"audits {spent['audit']:.0f} s, replays with the MAVLink output {spent['replay']:.0f} s",
          file=sys.stderr)
    return 0


def _frames(data: bytes) -> list:
    """The MAVLink messages in a capture, decoded (BAD_DATA for bytes that are not a frame)."""
    from pymavlink.dialects.v20 import common as mavlink2

    mav = mavlink2.MAVLink(None)
    mav.robust_parsing = True
    return mav.parse_buffer(data) or []


def first_mavlink_difference(before: bytes, after: bytes) -> str:
    """Where two MAVLink captures first differ: the frame's index and both frames, decoded."""
    a, b = _frames(before), _frames(after)
    for i, (x, y) in enumerate(zip(a, b)):
        if x.get_msgbuf() != y.get_msgbuf():
            return f"frame {i}: {x} != {y}"
    if len(a) != len(b):
        return f"{len(a)} frames != {len(b)} frames"
    return "same frames, other bytes between them"


def compare(before: Path, after: Path) -> int:
    names_b = {p.name for p in before.iterdir() if p.is_file()}
    names_a = {p.name for p in after.iterdir() if p.is_file()}
    differ = sorted(n for n in names_b & names_a
                    if not filecmp.cmp(before / n, after / n, shallow=False))
    only_b, only_a = sorted(names_b - names_a), sorted(names_a - names_b)
    for n in differ:
        print(f"DIFFERS: {n}")
        if n.endswith(".mavlink"):
            print(f"  first: {first_mavlink_difference((before / n).read_bytes(), (after / n).read_bytes())}")
    for n in only_b:
        print(f"only in {before}: {n}")
    for n in only_a:
        print(f"only in {after}: {n}")
    same = len(names_b & names_a) - len(differ)
    print(f"{len(names_b | names_a)} files, {same} identical, {len(differ)} differ, "
          f"{len(only_b) + len(only_a)} on one side only")
    return 1 if differ or only_b or only_a else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("outdir", type=Path)
    r.add_argument("--more", action="store_true", help="also ~/.cache/mavnav-flightlogs")
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    a = ap.parse_args()
    if a.cmd == "run":
        return run(a.outdir, a.more)
    return compare(a.before, a.after)


if __name__ == "__main__":
    sys.exit(main())
