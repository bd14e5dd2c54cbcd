"""A group of click options handed to the command as one dict: the flags the user gave.

``@flag_group(options, names, into)`` adds ``options`` to a command and
passes it, instead of one keyword argument per option, ``into=`` a dict of
those in ``names`` given on the command line (or through the environment);
an option left at its default is left out, so that a configuration value
can apply instead (``mavnav.config.with_overrides``).
"""

from __future__ import annotations

import functools
from typing import Callable, Sequence

import click
from click.core import ParameterSource

_NOT_GIVEN = (ParameterSource.DEFAULT, ParameterSource.DEFAULT_MAP, None)


def flag_group(options: Sequence[Callable], names: Sequence[str], into: str) -> Callable[[Callable], Callable]:
    def decorate(f: Callable) -> Callable:
        @functools.wraps(f)
        def command(*args, **kw):
            ctx = click.get_current_context()
            values = {name: kw.pop(name) for name in names if name in kw}
            kw[into] = {name: v for name, v in values.items() if ctx.get_parameter_source(name) not in _NOT_GIVEN}
            return f(*args, **kw)

        for option in reversed(options):
            command = option(command)
        return command

    return decorate


__all__ = ["flag_group"]
