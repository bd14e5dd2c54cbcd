"""Which vehicles height integrity applies to, as one table.

mavnav's model is an air vehicle over a reference: a baro that measures
static air pressure, a GNSS altitude, a downward rangefinder over the ground
near the reference. On water that model does not fit:

* a **submarine** (ArduSub): its first pressure sensor sits in the sealed
  enclosure (air at the enclosure's temperature, not the outside), its depth
  sensor measures water pressure (about 10 kPa per metre), it has no GNSS
  under water, and its sonar measures the seabed below, not the height above
  a reference;
* a **surface vessel** stays on the water's surface; its height is the sea
  level, its baro measures weather, and a downward sonar measures depth.

A height monitor run on them raises alarms from a model that does not fit
(43.6 m RMS against ArduSub's own depth on ``ardusub_rov_sonar_2023.tlog``).
So for these classes mavnav says, once, that height integrity does not apply,
and drops the height samples; the monitor is then unavailable with that
reason, never in alarm. Depth integrity (the water-pressure sensor with the
sonar as clearance) would be a different model, not built.
"""

from __future__ import annotations

from typing import Optional

from ..samples import BaroHeight, GnssHeight, RangeHeight, Rejected
from ..sensors import RANGE_STREAM

# MAV_TYPE -> why height integrity does not apply (absent: it applies)
NOT_APPLICABLE_MAV_TYPES = {
    11: "a surface vessel (MAV_TYPE_SURFACE_BOAT): its height is the water's surface, its sonar measures depth",
    12: "a submarine (MAV_TYPE_SUBMARINE): its pressure sensors measure the enclosure and water depth, "
        "its sonar the seabed",
}
# onboard logs name the vehicle by firmware ("sub", "boat"): the same classes
NOT_APPLICABLE_KINDS = {"sub": NOT_APPLICABLE_MAV_TYPES[12], "boat": NOT_APPLICABLE_MAV_TYPES[11]}


def not_applicable_reason(mav_type: Optional[int] = None, kind: str = "") -> Optional[str]:
    """Why height integrity does not apply to this vehicle, or None when it does."""
    if mav_type is not None and mav_type in NOT_APPLICABLE_MAV_TYPES:
        return NOT_APPLICABLE_MAV_TYPES[mav_type]
    return NOT_APPLICABLE_KINDS.get(kind)


def notice_text(reason: str) -> str:
    return (f"height integrity does not apply to {reason}; its baro, GNSS and rangefinder "
            "samples are not used and the monitor stays unavailable")


def is_height_input(event) -> bool:
    """A baro, GNSS or rangefinder sample, or a refused rangefinder reading."""
    return isinstance(event, (BaroHeight, GnssHeight, RangeHeight)) or (
        isinstance(event, Rejected) and event.sensor == RANGE_STREAM)
