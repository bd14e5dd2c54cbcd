"""A source's state over time, reporting each change as an AlarmEvent."""

from __future__ import annotations

from typing import Optional

from ..report import NAN, AlarmEvent, SourceStatus


class SourceTracker:
    """``clear_us``: a caution returns to nominal only once the source has been
    clean that long (hysteresis: no flapping of alarms and STATUSTEXTs)."""

    def __init__(self, source: str, t_us: int, boot: int, state: str = "nominal", reason: str = "start",
                 clear_us: int = 0):
        self.source = source
        self.state = state
        self.since_us = t_us
        self.reason = reason
        self.boot = boot
        self.clear_us = clear_us
        self._clean_since: Optional[int] = None
        self._status: Optional[SourceStatus] = None  # built once per change of state or reason
        # window_status with no test shown (NaN statistic and threshold): the same
        # (frozen) object until the state, its start, the reason or the rejections change
        self._idle_key: Optional[tuple] = None
        self._idle: Optional[SourceStatus] = None

    def set(self, state: str, t_us: int, reason: str) -> Optional[AlarmEvent]:
        if state == self.state:
            self._clean_since = None
            self.reason = reason if state != "nominal" else self.reason
            return None
        if state == "nominal" and self.state == "caution" and self.clear_us > 0:
            if self._clean_since is None:
                self._clean_since = t_us
            if t_us - self._clean_since < self.clear_us:
                return None
        self._clean_since = None
        ev = AlarmEvent(t_us=t_us, boot=self.boot, source=self.source, state=state,  # type: ignore[arg-type]
                        previous=self.state, reason=reason)  # type: ignore[arg-type]
        self.state, self.since_us, self.reason = state, t_us, reason
        return ev

    def status(self, **extra) -> SourceStatus:
        """The current status; without ``extra`` the same (frozen) object until the state,
        its start or its reason changes: a report per change, not per epoch."""
        if extra:
            return SourceStatus(state=self.state, since_t_s=self.since_us * 1e-6, reason=self.reason, **extra)  # type: ignore[arg-type]
        st = self._status
        if st is None or st.state != self.state or st.reason != self.reason or st.since_t_s != self.since_us * 1e-6:
            st = self._status = SourceStatus(state=self.state, since_t_s=self.since_us * 1e-6,  # type: ignore[arg-type]
                                             reason=self.reason)
        return st

    def window_status(self, window_stat: float, window_high: float, rejected: int) -> SourceStatus:
        """``status(window_stat=..., window_low=NaN, window_high=..., rejected=...)``,
        built positionally (once per source per epoch); with no test shown (a NaN
        statistic and threshold, a source without data or out) once per change."""
        if window_stat != window_stat and window_high != window_high:
            key = (self.state, self.since_us, self.reason, rejected)
            if key != self._idle_key:
                self._idle_key = key
                self._idle = SourceStatus(self.state, self.since_us * 1e-6, self.reason,  # type: ignore[arg-type]
                                          NAN, NAN, NAN, rejected)
            return self._idle  # type: ignore[return-value]
        return SourceStatus(self.state, self.since_us * 1e-6, self.reason,  # type: ignore[arg-type]
                            window_stat, NAN, window_high, rejected)
