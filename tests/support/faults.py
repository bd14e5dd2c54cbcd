"""Faults applied to synthetic sample streams (truth is known, onset exact)."""

from __future__ import annotations

import dataclasses


from mavnav.samples import BaroHeight, GnssHeight, RangeHeight

KINDS = {"gnss": GnssHeight, "rangefinder": RangeHeight, "baro": BaroHeight}
FIELD = {"gnss": "height_ref_m", "rangefinder": "height_agl_m", "baro": "height_ref_m"}


def apply_fault(samples, source, kind, onset_s, duration_s, magnitude, t0_us=1_000_000, seed=0):
    """kind: step (m), ramp (m/s), dropout, freeze, spikes (every 3rd sample
    off by ``magnitude``). Returns a new list."""
    cls, field = KINDS[source], FIELD[source]
    on, off = t0_us + int(onset_s * 1e6), t0_us + int((onset_s + duration_s) * 1e6)
    out = []
    frozen = None
    n = 0
    for s in samples:
        if isinstance(s, cls) and on <= s.t_us < off:
            n += 1
            if kind == "dropout":
                continue
            if kind == "spikes" and n % 3:
                out.append(s)
                continue
            v = getattr(s, field)
            if kind in ("step", "spikes"):
                v = v + magnitude
            elif kind == "ramp":
                v = v + magnitude * (s.t_us - on) * 1e-6
            elif kind == "freeze":
                frozen = v if frozen is None else frozen
                v = frozen
            s = dataclasses.replace(s, **{field: v})
        out.append(s)
    return out
