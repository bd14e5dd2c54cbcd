"""The sensor vocabulary, written once: from ingestion to reports.

:class:`Sensor` names every sensor and every source a report speaks of. It
is a ``str``-valued enum: a member *is* its value (``Sensor.GNSS ==
"gnss"``, same hash, ``str()``, ``format()`` and ``repr()`` as the plain
string), so dictionaries, sets, JSON, CSV and f-strings see exactly the
words they saw before, and a plain string still finds a member's entry.

The members:

* the three height sensors, which are also the bank's channels:
  ``gnss``, ``rangefinder``, ``baro``;
* ``imu`` (the inertial samples) and ``ins`` (the inertial solution as a
  fault hypothesis: the monitor's ``gnss``, ``rangefinder``, ``baro``,
  ``ins``);
* ``autopilot``: the autopilot's own height estimate (compared, never fused);
* the two report sources that are not one sensor: ``baro_ins`` (the baro or
  the INS: the reference channel) and ``input`` (the telemetry itself).

Other spellings live on in serialised outputs and are kept there byte for
byte; each is declared here, once, and read through a member:

* :attr:`Sensor.short`: the short form in column, pair and STATUSTEXT names
  (``rng`` for the rangefinder, ``baro`` for ``baro_ins``: ``gnss-rng``,
  ``rng_ok``);
* :attr:`Sensor.stream`: the ingestion stream kind (sample counters, gaps,
  ``Rejected.sensor``, the viewer's input lanes): ``range`` for the
  rangefinder;
* :attr:`Sensor.word`: the word for a person (``GNSS``, ``baro+INS``,
  ``telemetry``).

``Sensor("rng")``, ``Sensor("range")`` and ``Sensor("baro+INS")`` parse the
old spellings. Hot paths that key dictionaries by a literal keep the plain
``str`` (a member's entry is found by the literal, and the reverse, at the
cost of one string comparison); the constants below are the names to use
everywhere else.
"""

from __future__ import annotations

from enum import Enum


class Sensor(str, Enum):
    GNSS = "gnss"
    RANGEFINDER = "rangefinder"
    BARO = "baro"
    INS = "ins"
    IMU = "imu"
    AUTOPILOT = "autopilot"
    BARO_INS = "baro_ins"  # report source: the baro or the INS (the reference channel)
    INPUT = "input"  # report source: the telemetry itself (rates, gaps, link)

    # a member reads, prints and formats as its value on every Python (3.10's
    # (str, Enum) formats as the value but prints "Sensor.GNSS"; 3.11's prints
    # and formats as "Sensor.GNSS"): outputs never see the enum
    __str__ = str.__str__
    __format__ = str.__format__
    __repr__ = str.__repr__

    @property
    def short(self) -> str:
        """The short form in column, pair and STATUSTEXT names (``rng``)."""
        return _SHORT.get(self, self.value)

    @property
    def stream(self) -> str:
        """The ingestion stream kind (``range`` for the rangefinder)."""
        return _STREAM.get(self, self.value)

    @property
    def word(self) -> str:
        """The word for a person (``GNSS``, ``baro+INS``, ``telemetry``)."""
        return _WORD.get(self, self.value)

    @classmethod
    def _missing_(cls, value):
        return _ALIASES.get(value)


GNSS = Sensor.GNSS
RANGEFINDER = Sensor.RANGEFINDER
BARO = Sensor.BARO
INS = Sensor.INS
IMU = Sensor.IMU
AUTOPILOT = Sensor.AUTOPILOT
BARO_INS = Sensor.BARO_INS
INPUT = Sensor.INPUT

_SHORT = {RANGEFINDER: "rng", BARO_INS: "baro"}
_STREAM = {RANGEFINDER: "range"}
_WORD = {GNSS: "GNSS", BARO_INS: "baro+INS", INPUT: "telemetry"}
_ALIASES = {"rng": RANGEFINDER, "range": RANGEFINDER, "baro+INS": BARO_INS}

# The groups, in the order reports use.
CHANNELS = (GNSS, RANGEFINDER, BARO)  # the bank's channels, in its order
SOURCES = (GNSS, RANGEFINDER, BARO_INS, INPUT)  # what a report's states are of
SENSOR_SOURCES = (GNSS, RANGEFINDER, BARO_INS)  # the sources that are sensors
HYPOTHESES = (GNSS, RANGEFINDER, BARO, INS)  # the monitor's single-fault hypotheses
REPORT_SOURCE = {GNSS: GNSS, RANGEFINDER: RANGEFINDER, BARO: BARO_INS, INS: BARO_INS}  # hypothesis -> source
INPUTS = (IMU, BARO, GNSS, RANGEFINDER)  # the inputs whose rates an audit checks

# The ingestion stream kinds as plain strings (the normaliser's per-sample path).
IMU_STREAM = IMU.stream
BARO_STREAM = BARO.stream
GNSS_STREAM = GNSS.stream
RANGE_STREAM = RANGEFINDER.stream
AUTOPILOT_STREAM = AUTOPILOT.stream
