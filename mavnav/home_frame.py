"""Heights above the autopilot's current home, while the filters keep their first reference.

The height references (the baro reference pressure, the GNSS reference
altitude) are fixed once, at the autopilot's home as it was when mavnav
connected (:mod:`mavnav.ingest.references`). When the autopilot later moves
its home (a new home set at arming, at another altitude), the normaliser says
so with a :class:`~mavnav.samples.ReferenceMoved`; re-fixing the references
there would put the same step into every height at once, which the filters
and the monitor would rightly take for a fault. So the core keeps its frame,
and :class:`HomeFrame` moves what is *reported*: every height above the
reference (fused, each channel's, the raw baro and GNSS, the autopilot's)
is shown ``offset_m`` lower, i.e. above the new home. Heights above ground
(the rangefinder's), sigmas, differences, thresholds and protection levels
do not depend on the point and are left alone.

Pure and deterministic: the offset changes only where the event sits in the
stream (vehicle time order), never on a clock.
"""

from __future__ import annotations

from dataclasses import replace

from .report import EpochReport
from .samples import AutopilotHeight, BaroHeight, GnssHeight, ReferenceMoved

_ABOVE_REFERENCE = (BaroHeight, GnssHeight, AutopilotHeight)  # samples with a height_ref_m


class HomeFrame:
    """Turns samples and reports from the filters' frame into heights above the current home."""

    def __init__(self) -> None:
        self.offset_m = 0.0  # the current home's altitude above the point the references were fixed at

    def sample(self, s):
        """``s`` as the sinks see it (a copy with the height moved, or ``s`` itself)."""
        ts = type(s)
        if ts is ReferenceMoved:
            self.offset_m = s.offset_m
            return s
        if self.offset_m == 0.0 or ts not in _ABOVE_REFERENCE:
            return s
        return replace(s, height_ref_m=s.height_ref_m - self.offset_m)

    def report(self, r: EpochReport) -> EpochReport:
        d = self.offset_m
        if d == 0.0:
            return r
        return replace(
            r,
            height_fused_m=r.height_fused_m - d,
            channels=tuple(replace(c, height_ref_m=c.height_ref_m - d) for c in r.channels),
            baro_height_ref_m=r.baro_height_ref_m - d,
            gnss_height_ref_m=r.gnss_height_ref_m - d,
            autopilot_height_ref_m=r.autopilot_height_ref_m - d,
        )


HOME_WORDS = {"home": "HOME_POSITION", "autopilot_home": "GLOBAL_POSITION_INT's alt - relative_alt"}


def home_moved_text(s: ReferenceMoved) -> str:
    """What a :class:`~mavnav.samples.ReferenceMoved` means, in words (console, CSV, viewer)."""
    return (f"HOME MOVED {s.shift_m:+.2f} m to {s.alt_ref_msl_m:.2f} m MSL ({HOME_WORDS.get(s.origin, s.origin)}): "
            f"heights are now above the new home")
