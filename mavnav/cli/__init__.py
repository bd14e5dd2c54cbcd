"""The ``mavnav`` command line: a click group; each command lives in its own module.

The CLI is an edge: it is the only place that opens files and sockets, reads
the wall clock and chooses sinks. Errors meant for users (``MavnavError``)
print as one line and exit with status 2.
"""

from __future__ import annotations

import sys

import click

from ..errors import MavnavError


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except MavnavError as exc:
            click.echo(f"mavnav: error: {exc}", err=True)
            sys.exit(2)


@click.group(cls=_Group)
@click.version_option(package_name="mavnav")
def main() -> None:
    """mavnav: three-channel height estimation with integrity control over MAVLink.

    \b
    States (per source and overall: console, CSV 'alarm' column, viewer, STATUSTEXT):
      nominal      sensors agree, the height is protected (within the alert limit).
                   Nothing to do.
      caution      a source looks suspicious, not confirmed; the height is still
                   protected. Carry on, watch the named source, be ready.
      unavailable  too little left to protect the height (normal at start-up);
                   for one source: no usable data from it. Do not rely on the
                   height near the ground: keep a margin, use another reference;
                   if it lasts, check the sensors and the link.
      alarm        a source is confirmed faulty and excluded (named, with why);
                   'input': telemetry lost or too slow. Treat the autopilot's
                   altitude as suspect if it uses that source: stop height-critical
                   work, hold or climb to a safe height, cross-check, land with care.
    """


# Each command module registers itself on import.

from . import covariance  # noqa: E402,F401
from . import simulate  # noqa: E402,F401
from . import inject  # noqa: E402,F401
from . import run  # noqa: E402,F401
from . import audit  # noqa: E402,F401
