"""Errors mavnav raises on purpose. Each carries a one-line message for users."""


class MavnavError(Exception):
    """Base of every error mavnav reports to a user (one line, no traceback)."""


class ConfigError(MavnavError):
    """A configuration file is missing, unreadable, or has a bad/unknown key."""


class InputError(MavnavError):
    """Input that cannot be used at all (not a tlog, unreadable device...)."""


class NonFiniteInputError(MavnavError, ValueError):
    """A non-finite number was offered to the estimator; it is refused."""
