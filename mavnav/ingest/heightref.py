"""The normaliser's reference stage: where zero height is, for the baro and the GNSS.

:class:`HeightReferences` holds the baro and GNSS samples until their
reference is known (:class:`~.references.ReferenceResolver`), takes the
references from the autopilot's own reference point when it tells one
(HOME_POSITION, GLOBAL_POSITION_INT's home, the EKF origin with
LOCAL_POSITION_NED: the *anchor*), and follows a home that moves. The rules
are those of the :mod:`.normaliser` module docstring ("References",
"A home that moves"); this module knows no MAVLink field.

Each entry point returns what it releases, in order, for the normaliser to
pass on: :class:`~mavnav.samples.BaroHeight` and
:class:`~mavnav.samples.GnssHeight` samples (through its per-kind guard),
events (:class:`~mavnav.samples.ReferenceSet`,
:class:`~mavnav.samples.ReferenceMoved`, a
:class:`~mavnav.samples.Notice` of what the references wait for), and
:data:`GNSS_FIXED` once the GNSS reference is fixed (the autopilot's heights
held for it may go).
"""

from __future__ import annotations

import bisect
import math
from typing import Callable, List, NamedTuple, Optional, Tuple

from ..atmosphere import height_from_pressure_m, pressure_at_height_pa
from ..config import IngestConfig
from ..samples import BaroHeight, GnssHeight, Notice, ReferenceMoved, ReferenceSet
from .clock import VehicleClock
from .references import AnchoredValue, ReferenceResolver

REL_ALT_MAX_AGE_US = 1_000_000  # a baro sample pairs with the autopilot's height this close in time
ANCHOR_WINDOW_US = 1_000_000  # baro samples averaged for a reference from the autopilot (capped by startup_window_s)
WAIT_NOTICE_US = 1_000_000  # held this long for a reference: say what for
REL_HIST_MAX = 8192
HOME_CONFIRM_N = 3  # GLOBAL_POSITION_INT messages in a row that must show a moved home
ANCHORED = ("home", "autopilot_home", "ekf_origin")
GPI, LPN = "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"  # the autopilot's height streams, by name


class BaroItem(NamedTuple):
    """A static pressure on the vehicle clock, before the baro reference is known."""

    t_us: int
    recv_s: float
    boot: int
    p_pa: float


class GnssItem(NamedTuple):
    """A GNSS altitude on the vehicle clock, before the GNSS reference is known."""

    t_us: int
    recv_s: float
    boot: int
    alt_m: float  # MSL or above the ellipsoid (ingest.gnss_altitude)
    sigma_m: Optional[float]
    fix: int
    sats: int


class Anchor(NamedTuple):
    """The autopilot's reference point: where its origin is (``home``,
    ``autopilot_home``, ``ekf_origin``), its altitude MSL, and the stream
    of heights above it."""

    origin: str
    alt_msl_m: float
    rel_kind: str  # GLOBAL_POSITION_INT or LOCAL_POSITION_NED


class _HomePosition(NamedTuple):
    """The first HOME_POSITION: when (vehicle clock, boot) and its altitude MSL."""

    t_us: int
    boot: int
    alt_msl_m: float


class _RelHeight(NamedTuple):
    """The autopilot's height above its reference point at a vehicle time, and its vertical speed."""

    t_us: int
    height_m: float
    vel_up_mps: float


class _GnssFixed:
    __slots__ = ()

    def __repr__(self) -> str:
        return "GNSS_FIXED"


GNSS_FIXED = _GnssFixed()


class HeightReferences:
    """``clock``: the vehicle clock (read: the boot, the last time);
    ``last_recv()``: the link's latest receive time (events fixed before any
    sample needed them carry it)."""

    def __init__(self, cfg: IngestConfig, clock: VehicleClock, last_recv: Callable[[], Optional[float]]):
        self.cfg = cfg
        self.clock = clock
        self._last_recv = last_recv
        self.baro = ReferenceResolver("baro", cfg.baro_reference, _item_t, _mean_pressure, self._baro_anchored)
        self.gnss = ReferenceResolver("gnss", cfg.gnss_reference, _item_t, _mean_alt, self._gnss_anchored)
        self.anchor: Optional[Anchor] = None
        self._home_pos: Optional[_HomePosition] = None  # the first HOME_POSITION
        # the reference point as it moves with the autopilot's home (alt MSL), and what moved it last
        self._point_msl: Optional[float] = None
        self._home_last: dict = {}  # origin ("home", "autopilot_home") -> the last home altitude it gave
        self._gpi_home_cands: List[float] = []  # a moved GLOBAL_POSITION_INT home, not yet confirmed
        # the autopilot's height above its home / EKF origin, this boot, while the baro reference is open
        self._rel_hist: dict[str, List[_RelHeight]] = {GPI: [], LPN: []}
        self._wait_said: set = set()
        self.geoid_sep_m: Optional[float] = None  # GNSS: ellipsoid height - MSL altitude
        self.ekf_origin_msl_m: Optional[float] = None
        self._baro_tied = False  # the baro reference being released was taken at the datum

    # ------------------------------------------------------------------ entry points

    def pressure(self, item: BaroItem) -> list:
        out = self._baro_released(*self.baro.push(item))
        if self.baro.value is None:
            out += self._say_waiting(self.baro, item.recv_s)
        return out

    def gnss_altitude(self, item: GnssItem) -> list:
        out = self._gnss_released(*self.gnss.push(item))
        if self.gnss.value is None:
            out += self._say_waiting(self.gnss, item.recv_s)
        return out

    def home_position(self, alt_msl_m: float) -> list:
        """The autopilot's home (HOME_POSITION)."""
        if self._home_pos is None:
            t_us = self.clock.last_t_us if self.clock.last_t_us is not None else 0
            self._home_pos = _HomePosition(t_us, self.clock.boot, alt_msl_m)
        if self.anchor is None:
            self._home_last["home"] = alt_msl_m
            return self._set_anchor("home", alt_msl_m, GPI)
        return self._home_seen("home", alt_msl_m)

    def autopilot_home(self, t_us: int, alt_msl_m: float, home_msl_m: float, rel_m: float,
                       vel_up: float) -> Tuple[float, list]:
        """GLOBAL_POSITION_INT with a position and its home set: ``(its height above the
        point the references are fixed at, what it releases)``."""
        if self.anchor is not None:
            # above the point the references are fixed at, whatever home the autopilot has now
            rel_m = alt_msl_m - self.anchor.alt_msl_m
        self._note_rel(GPI, t_us, rel_m, vel_up)
        if self.anchor is None:
            self._home_last["autopilot_home"] = home_msl_m
            return rel_m, self._set_anchor("autopilot_home", home_msl_m, GPI)
        out = self._gpi_home(home_msl_m)
        if self.baro.value is None and self.baro.held:
            out += self._baro_released(*self.baro.retry())
        return rel_m, out

    def local_position(self, t_us: int, up_m: float, vel_up: float) -> list:
        """LOCAL_POSITION_NED: the height above the EKF origin."""
        self._note_rel(LPN, t_us, up_m, vel_up)
        if self.anchor is None and self.ekf_origin_msl_m is not None:
            return self._set_anchor("ekf_origin", self.ekf_origin_msl_m, LPN)
        if self.anchor is not None and self.baro.value is None and self.baro.held:
            return self._baro_released(*self.baro.retry())
        return []

    def ekf_origin(self, alt_msl_m: float) -> list:
        """GPS_GLOBAL_ORIGIN: the EKF origin's altitude."""
        self.ekf_origin_msl_m = alt_msl_m
        if self.anchor is None and self._rel_hist[LPN]:
            return self._set_anchor("ekf_origin", alt_msl_m, LPN)
        return []

    def settle(self) -> list:
        """The end of a boot or of the stream: references not yet known are
        taken from what is held (as at the end of a stream)."""
        out = self._baro_released(*self.baro.finish())
        return out + self._gnss_released(*self.gnss.finish())

    def new_boot(self) -> None:
        for hist in self._rel_hist.values():
            hist.clear()

    def gnss_ref_msl_m(self) -> Optional[float]:
        """The GNSS reference as an altitude MSL (None: not known yet)."""
        v = self.gnss.value
        if v is None:
            return None
        if self.cfg.gnss_altitude == "msl":
            return v
        return v - self.geoid_sep_m if self.geoid_sep_m is not None else None

    # ------------------------------------------------------------------ from the anchor

    def _baro_anchored(self, held, final):
        """The pressure at the autopilot's reference point: each baro sample moved
        down by the autopilot's height above that point at the same moment."""
        a = self.anchor
        if a is None or not held:
            return None
        origin, rel_kind = a.origin, a.rel_kind
        win = min(self.baro.window_us, ANCHOR_WINDOW_US)
        vals = []
        rel_max = 0.0
        t0 = b0 = None
        complete = final
        for t_us, _r, boot, p in held:  # BaroItem
            if t0 is not None and (t_us - t0 >= win or boot != b0):
                complete = True
                break
            rel = self._rel_at(t_us, boot, rel_kind)
            if rel is None:
                continue
            if t0 is None:
                t0, b0 = t_us, boot
            rel_max = max(rel_max, abs(rel))
            vals.append(p / pressure_at_height_pa(rel, 1.0))  # p was measured rel above the point
        if vals:
            if not complete:
                return None
            self._baro_tied = rel_max <= self.cfg.baro_reference.at_datum_max_m
            return AnchoredValue(sum(vals) / len(vals), origin)
        if origin == "home" and self._home_pos is not None:
            # HOME_POSITION and no height above it: home is where the vehicle was when it was set
            v = self._baro_at_home(held, final)
            if v is not None:
                return AnchoredValue(v, origin)
        return None

    def _baro_at_home(self, held, final) -> Optional[float]:
        """Only once no height above home came for ``startup_window_s`` after HOME_POSITION
        (a link without GLOBAL_POSITION_INT): the pressure around it."""
        th, bh = self._home_pos.t_us, self._home_pos.boot
        w = self.baro.window_us
        after = [it for it in held if (it.boot == bh and it.t_us > th) or it.boot > bh]
        if not final and (not after or after[-1].boot == bh and after[-1].t_us - th < w):
            return None  # a GLOBAL_POSITION_INT may still come
        before = [it for it in held if it.boot == bh and th - w <= it.t_us <= th]
        if before:
            self._baro_tied = True  # the pressure where home was set, as it was set
            return _mean_pressure(before)
        if not after:
            return None
        t0 = after[0].t_us
        return _mean_pressure([it for it in after if it.t_us - t0 <= w and it.boot == after[0].boot])

    def _gnss_anchored(self, held, final):
        a = self.anchor
        if a is None:
            return None
        origin, alt_msl = a.origin, a.alt_msl_m
        if self.cfg.gnss_altitude == "msl":
            return AnchoredValue(alt_msl, origin)
        if self.geoid_sep_m is None:
            return None
        return AnchoredValue(alt_msl + self.geoid_sep_m, origin)

    def _rel_at(self, t_us: int, boot: int, kind: str) -> Optional[float]:
        """The autopilot's height above its reference point at ``t_us`` (None: none within 1 s)."""
        if boot != self.clock.boot:
            return None
        hist = self._rel_hist[kind]
        i = bisect.bisect_left(hist, (t_us,))
        best: Optional[_RelHeight] = None  # the nearest within REL_ALT_MAX_AGE_US, and how far
        best_d = 0
        for j in (i - 1, i):
            if 0 <= j < len(hist):
                d = abs(hist[j].t_us - t_us)
                if d <= REL_ALT_MAX_AGE_US and (best is None or d < best_d):
                    best, best_d = hist[j], d
        if best is None:
            return None
        if not math.isfinite(best.vel_up_mps):
            return best.height_m
        return best.height_m + best.vel_up_mps * (t_us - best.t_us) * 1e-6

    def _note_rel(self, kind: str, t_us: int, rel_m: float, vel_up: float) -> None:
        if self.baro.value is not None or not math.isfinite(rel_m):
            return
        hist = self._rel_hist[kind]
        if len(hist) >= REL_HIST_MAX:
            del hist[: REL_HIST_MAX // 2]
        bisect.insort(hist, _RelHeight(t_us, rel_m, vel_up))

    def _set_anchor(self, origin: str, alt_msl_m: float, rel_kind: str) -> list:
        """The autopilot's reference point is known: fix what waits for it (first one wins)."""
        if self.anchor is not None:
            return []
        self.anchor = Anchor(origin, alt_msl_m, rel_kind)
        self._point_msl = alt_msl_m
        out = []
        if self.baro.value is None:
            out += self._baro_released(*self.baro.retry())
        if self.gnss.value is None:
            out += self._gnss_released(*self.gnss.retry())
        return out

    # ------------------------------------------------------------------ a home that moves

    def _home_seen(self, origin: str, alt_msl_m: float) -> list:
        """A home altitude from the autopilot after the reference point was fixed: a move
        when this source's home changed and is away from the point."""
        if not self.cfg.follow_home or self.anchor is None:
            return []
        tol = self.cfg.home_move_min_m
        last = self._home_last.get(origin)
        self._home_last[origin] = alt_msl_m
        if last is not None and abs(alt_msl_m - last) <= tol:
            return []  # the same home again
        if abs(alt_msl_m - self._point_msl) <= tol:
            return []
        shift = alt_msl_m - self._point_msl
        self._point_msl = alt_msl_m
        t_us = self.clock.last_t_us if self.clock.last_t_us is not None else 0
        return [ReferenceMoved(t_us=t_us, recv_s=self._last_recv() or 0.0, boot=self.clock.boot,
                               alt_ref_msl_m=alt_msl_m, shift_m=shift, offset_m=alt_msl_m - self.anchor.alt_msl_m,
                               origin=origin)]

    def _gpi_home(self, home_msl_m: float) -> list:
        """GLOBAL_POSITION_INT's home, followed only on a link without HOME_POSITION and only
        once ``HOME_CONFIRM_N`` messages in a row show the same moved value."""
        if self._home_pos is not None:
            return []  # HOME_POSITION says where home is
        last = self._home_last.get("autopilot_home", self._point_msl)
        tol = self.cfg.home_move_min_m
        cands = self._gpi_home_cands
        if last is None or abs(home_msl_m - last) <= tol:
            cands.clear()
            return []
        if cands and abs(home_msl_m - cands[0]) > tol:
            cands.clear()
        cands.append(home_msl_m)
        if len(cands) >= HOME_CONFIRM_N:
            cands.clear()
            return self._home_seen("autopilot_home", home_msl_m)
        return []

    # ------------------------------------------------------------------ what goes out

    def _say_waiting(self, ref: ReferenceResolver, recv_s: float) -> list:
        if ref.kind in self._wait_said or ref.cfg.source != "home" or ref.held_span_us() < WAIT_NOTICE_US:
            return []
        self._wait_said.add(ref.kind)
        what = "baro" if ref.kind == "baro" else "GNSS"
        return [Notice(recv_s, "waiting_reference",
                       f"waiting for HOME_POSITION or GLOBAL_POSITION_INT to fix the {what} height reference "
                       f"(at most {ref.cfg.home_wait_s:g} s, then the start-up mean)")]

    def _baro_released(self, origin: Optional[str], items: List[BaroItem]) -> list:
        if not items and origin is None:
            return []
        out: list = []
        p_ref = self.baro.value
        if origin is not None:
            first = items[0] if items else None
            alt = self.anchor.alt_msl_m if origin in ANCHORED and self.anchor is not None else None
            out.append(self._reference_set("baro", p_ref, alt, origin, first, at_datum=self._baro_tied))
            self._baro_tied = False
        inst = self.cfg.baro_instance
        for t_us, recv_s, boot, p_pa in items:
            h = height_from_pressure_m(p_pa, p_ref)
            out.append(BaroHeight(t_us, recv_s, boot, h, p_pa, inst))
        return out

    def _gnss_released(self, origin: Optional[str], items: List[GnssItem]) -> list:
        out: list = []
        if origin is not None:
            out.append(self._reference_set("gnss", self.gnss.value, self.gnss_ref_msl_m(), origin,
                                           items[0] if items else None))
        ref = self.gnss.value
        for t_us, recv_s, boot, alt_m, sigma_m, fix, sats in items:
            out.append(GnssHeight(t_us, recv_s, boot, alt_m - ref, alt_m, sigma_m, fix, sats))
        if origin is not None:
            out.append(GNSS_FIXED)
        return out

    def _reference_set(self, kind, value, alt_msl, origin, item, at_datum: bool = False) -> ReferenceSet:
        if item:
            t_us, recv_s, boot = item.t_us, item.recv_s, item.boot
        else:  # fixed before any sample needed it (from the autopilot's home)
            t_us = self.clock.last_t_us if self.clock.last_t_us is not None else 0
            recv_s, boot = (self._last_recv() or 0.0), self.clock.boot
        return ReferenceSet(t_us=t_us, recv_s=recv_s, boot=boot, kind=kind, value=value, alt_ref_msl_m=alt_msl,
                            origin=origin, at_datum=at_datum)


def _item_t(item):
    """``(t_us, boot)`` of a held baro or GNSS item."""
    return item.t_us, item.boot


def _mean_pressure(items: List[BaroItem]) -> float:
    return sum(it.p_pa for it in items) / len(items)


def _mean_alt(items: List[GnssItem]) -> float:
    return sum(it.alt_m for it in items) / len(items)


__all__ = ["HeightReferences", "BaroItem", "GnssItem", "Anchor", "GNSS_FIXED"]
