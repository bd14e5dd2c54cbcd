"""A log file's first bytes, or a one-line :class:`~mavnav.errors.InputError`."""

from __future__ import annotations

from ...errors import InputError


def read_head(path, n: int) -> bytes:
    """Up to ``n`` bytes from the start of ``path``; InputError if it cannot be read."""
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
