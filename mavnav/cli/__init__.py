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
    """mavnav: three-channel height estimation with integrity control over MAVLink."""


# Each command module registers itself on import.

from . import covariance  # noqa: E402,F401
from . import simulate  # noqa: E402,F401
from . import inject  # noqa: E402,F401
from . import run  # noqa: E402,F401
from . import audit  # noqa: E402,F401
