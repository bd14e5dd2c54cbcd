"""``mavnav inject IN.tlog -o OUT.tlog FAULT...``: faults with a known onset in a real log."""

from __future__ import annotations

from typing import Optional, Tuple

import click

from ..errors import InputError
from . import main
from .honest import check_outputs


def _kinds_help() -> str:
    from ..sim.scenario import FAULT_MAGNITUDE, FAULT_SOURCE

    lines = []
    for kind, src in FAULT_SOURCE.items():
        meaning = FAULT_MAGNITUDE[kind] or "no magnitude"
        lines.append(f"  {kind:<17} [{src}] {meaning}")
    return "\n".join(lines)


_SUMMARY = "Inject FAULTs into a recorded tlog from a given vehicle time."

_HELP = _SUMMARY + """

Every record outside the fault windows (and every message type a fault does
not touch) is copied byte for byte, corrupt frames and timestamps included.
Faulted messages keep their MAVLink version, seq, sysid and compid and get a
correct CRC. A sidecar OUT.faults.json names each fault, its window in
vehicle time, the boot it applied in and how many records it changed.

\b
FAULT syntax:  KIND:key=value,key=value,...
  onset=S        vehicle time (time_boot_ms clock, seconds) of the onset
  duration=S     length of the window (omit: until the end of the log)
  magnitude=M    size of the fault, unit by kind (below)
  probability=P  rng_spikes: fraction of readings hit (default 0.3)
  mode=M         gnss_dropout: nofix|silent; rng_dropout: invalid|silent
  messages=A|B   only these message types (e.g. SCALED_PRESSURE2)
  seed=N         random draws of gnss_noise and rng_spikes (default 0)
  boot=N         the boot (0 = first) in which onset counts (default: first reached)

\b
Kinds [source] and magnitude:
{kinds}

\b
Examples:
  mavnav inject in.tlog -o out.tlog gnss_step:onset=60,duration=20,magnitude=10
  mavnav inject in.tlog -o out.tlog rng_dropout:onset=30,duration=5,mode=silent baro_ramp:onset=90,duration=20,magnitude=0.4
"""


class _InjectCommand(click.Command):
    """The kinds in the help live with the simulator (pydantic, numpy): the
    full text is built when it is shown, the summary line serves the list of
    commands."""

    def format_help_text(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        self.help = _HELP.format(kinds=_kinds_help())
        super().format_help_text(ctx, formatter)


@main.command("inject", cls=_InjectCommand, help=_SUMMARY)
@click.argument("in_path", metavar="IN.tlog", type=click.Path(dir_okay=False))
@click.argument("faults", metavar="FAULT...", nargs=-1, required=True)
@click.option("-o", "--output", "out_path", required=True, type=click.Path(dir_okay=False),
              help="The faulted .tlog to write.")
@click.option("--sysid", type=click.IntRange(1, 255), default=None,
              help="System id of the vehicle (default: the first autopilot HEARTBEAT).")
def inject_cmd(in_path: str, faults: Tuple[str, ...], out_path: str, sysid: Optional[int]) -> None:
    from ..sim.faults import parse_fault, sidecar_path, write_sidecar
    from ..sim.inject import inject_file

    parsed = [parse_fault(spec) for spec in faults]
    if str(in_path) == str(out_path):
        raise InputError("the output must not overwrite the input")
    check_outputs({"-o": out_path, "the fault sidecar": sidecar_path(out_path)})
    report = inject_file(in_path, out_path, parsed, sysid)
    side = sidecar_path(out_path)
    write_sidecar(side, report)
    for f in report["faults"]:
        where = "never reached" if f["boot"] is None else f"boot {f['boot']}"
        click.echo(
            f"{f['kind']}: onset {f['onset_s']:g} s ({where}), "
            f"{f['records_modified']} records changed, {f['records_dropped']} removed"
        )
    click.echo(f"{out_path}: written; faults -> {side}")
