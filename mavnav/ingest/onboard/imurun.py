"""A run of consecutive IMU samples of an onboard log, passed as columns.

An onboard log's IMU (200-400 Hz) is most of its samples: about 40 between
two baro epochs. :meth:`~.source.OnboardSource.runs` yields each stretch of
consecutive IMU samples (nothing else between them in the merged order, no
gap before any but the first) as one :class:`ImuRun` instead of one
:class:`~mavnav.samples.SpecificForceUp` per row, and
:func:`mavnav.pipeline.run` takes it through the monitor
(:meth:`~mavnav.monitor.Monitor.push_run`) and the sinks (their ``imu_run``
hook) a slice at a time: each slice ends at the sample that completes an
epoch, so every hook sees the same samples before the same epochs as with
one object per sample. :meth:`ImuRun.samples` builds those objects, the same
as the per-sample stream (``tests/test_ingest_imu_runs.py`` checks that the
two streams agree, and that an audit through either gives the same result).

The times of a run increase strictly (the source's per-kind guard has
dropped duplicates and samples out of order), as every consumer assumes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, List, Optional

if TYPE_CHECKING:
    import numpy as np

from ...samples import SpecificForceUp


class ImuRun:
    """Samples ``lo .. hi - 1`` of the IMU columns ``t_us`` (int, us) and
    ``f_up`` (float, m/s^2), from the IMU named ``source``; ``boot`` 0 and
    ``recv_s`` the vehicle time in seconds, as every onboard sample.
    ``t_arr``, ``f_arr``: the same columns as int64 and float64 arrays (or
    None), for the epoch builder's compiled pass to take as views."""

    __slots__ = ("t_us", "f_up", "lo", "hi", "source", "t_arr", "f_arr")

    def __init__(self, t_us: List[int], f_up: List[float], lo: int, hi: int, source: str,
                 t_arr: Optional[np.ndarray] = None, f_arr: Optional[np.ndarray] = None):
        self.t_us = t_us
        self.f_up = f_up
        self.lo = lo
        self.hi = hi
        self.source = source
        self.t_arr = t_arr
        self.f_arr = f_arr

    def __len__(self) -> int:
        return self.hi - self.lo

    def samples(self, i: int, j: int) -> List[SpecificForceUp]:
        """Samples ``i .. j - 1`` (column indices) as objects, as the per-sample stream yields them."""
        t, f, name = self.t_us, self.f_up, self.source
        return [SpecificForceUp(t[k], t[k] * 1e-6, 0, f[k], name) for k in range(i, j)]

    def __repr__(self) -> str:
        return f"ImuRun({self.source!r}, {self.hi - self.lo} samples from t_us={self.t_us[self.lo]})"
