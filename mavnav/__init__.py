"""mavnav: a live telemetry integrity monitor for vehicle height over MAVLink.

Conventions, written once:

* Heights are positive up, in metres, and every height names its datum:
  ``_msl`` (mean sea level), ``_ref`` (above the reference point, normally
  home / the landing point), ``_agl`` (above the ground below the vehicle).
* Units are in names: ``_m``, ``_mps``, ``_mps2``, ``_s``, ``_us``, ``_pa``.
* Two clocks, never mixed. *Vehicle time* (``t_us``, integer microseconds,
  from the messages' own ``time_usec`` / ``time_boot_ms``) drives every
  filter step. *Receive time* (``recv_s``, Unix seconds) is only for link
  health, latency and staleness.
* The core (``kalman``, ``channel``, ``epochs``, ``monitor``) is pure and
  deterministic: no wall clock, no I/O. Sources, sinks and the CLI are the
  edges.
* Sensors and report sources have one vocabulary, :class:`mavnav.sensors.Sensor`
  (a ``str`` enum: ``gnss``, ``rangefinder``, ``baro``, ``ins``, ``imu``,
  ``autopilot``, ``baro_ins``, ``input``); the older spellings kept in
  outputs (``rng``, ``range``, ``baro+INS``) are declared there once.
* Channel state ``[H, Vz, dH, da]``: height above the reference, vertical
  speed (up), barometer bias, accelerometer bias. Indices are named in
  :mod:`mavnav.channel`.

The estimator follows Ivanov, Moskvitin, Ivanov, Lezhneva (Transactions TSTU,
2024, 30(4), 608-620) with its errata fixed. ``MODEL.md`` in the docstrings is
the model written out with the errata, ``../shared/docs/MODEL.md`` (beside the
repository, not in it); ``docs/covariance.md`` reproduces the paper's
covariance study and shows the errata, ``docs/integrity.md`` explains the
monitor's logic.
"""

__version__ = "0.1.0"
