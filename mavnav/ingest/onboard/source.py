"""An onboard log as a stream of mavnav samples: the same types, rules and order as a tlog.

:class:`OnboardSource` decodes a DataFlash or ULog file (:mod:`.dataflash`,
:mod:`.ulog`) into columns, then applies the rules the tlog normaliser
applies to MAVLink, vectorised over whole series:

* **Specific force up.** Each IMU sample takes the attitude's 'down' row
  interpolated linearly between the two attitude records around it (and
  renormalised); with no attitude record within ``attitude_max_age_s`` it
  is refused (``no_attitude``).
* **References.** Baro: the configured pressure, else the mean pressure
  over the first ``startup_window_s`` of baro samples (an onboard log
  starts at boot or at arming, on the ground: the home the autopilot sets
  at arming is that place). GNSS: the configured altitude, else the
  autopilot's logged home altitude (``home``), else the mean over the first
  ``startup_window_s`` of fixes (``startup``). Both are known before the
  first sample, so nothing is held.
* **GNSS.** Fixes below ``min_fix_type`` are filtered (counted). The
  reported vertical accuracy travels with the sample.
* **Rangefinder.** Downward only; a reading the driver flags invalid, out of
  its ``[min, max]`` (the log's limits, else the configured ones), stuck
  (``rangefinder_stuck_s`` of one value while the baro moved), or beyond
  ``rangefinder_max_tilt_deg`` is refused with a
  :class:`~mavnav.samples.Rejected` whose ``sensor`` is ``"range"``; the
  rest are tilt-corrected.
* **Autopilot height.** Above the GNSS reference when the EKF origin (or
  home) altitude and the GNSS reference are both known, else in the
  autopilot's own datum (``stats.autopilot_reference`` says which).
* **Order.** All samples merged by vehicle time (ties: IMU, baro, GNSS,
  rangefinder, autopilot), through the rule of :class:`~..streams.KindGuard`
  as tlogs (gaps reported; computed per kind at once by
  :func:`_guard_series`). ``recv_s`` is the vehicle time in seconds: an
  onboard log has no receive clock.

An onboard log is one boot: no reboots, no link.
"""

from __future__ import annotations

import dataclasses
import math
from itertools import repeat
from pathlib import Path
from typing import Iterator, List, Optional, Union

import numpy as np

from ...atmosphere import heights_from_pressures_m
from ...config import IngestConfig
from ...errors import InputError
from ...jit import njit
from ...samples import (
    AutopilotHeight,
    BaroHeight,
    Gap,
    GnssHeight,
    Notice,
    RangeHeight,
    ReferenceSet,
    Rejected,
    SpecificForceUp,
)
from ...sensors import AUTOPILOT_STREAM, BARO_STREAM, GNSS_STREAM, IMU_STREAM, RANGE_STREAM
from ..decoders import MAX_SPECIFIC_FORCE_MPS2  # the tlog decoders' limit, one for both
from ..stats import GapRecord, IngestStats, ReferenceRecord, VehicleInfo
from ..vehicle_class import not_applicable_reason, notice_text
from .head import read_head
from .imurun import ImuRun
from .record import OnboardRecord

PathLike = Union[str, Path]
ULOG_MAGIC = b"ULog\x01\x12\x35"

# merge order at equal times
_IMU, _BARO, _GNSS, _RANGE, _RANGE_REJ, _AP, _IMU_REJ = range(7)
_KIND = {_IMU: IMU_STREAM, _BARO: BARO_STREAM, _GNSS: GNSS_STREAM, _RANGE: RANGE_STREAM, _AP: AUTOPILOT_STREAM}  # samples, not events
_VERDICT = {1: "duplicate", 2: "out_of_order"}


def detect_onboard(head: bytes) -> Optional[str]:
    """'dataflash', 'ulog' or None, from a file's first bytes."""
    from .dataflash import is_dataflash

    if head.startswith(ULOG_MAGIC):
        return "ulog"
    if is_dataflash(head):
        return "dataflash"
    return None


def read_record(path: PathLike) -> OnboardRecord:
    """Decode an onboard log of either format (detected by content)."""
    kind = detect_onboard(read_head(path, 16))
    if kind == "dataflash":
        from .dataflash import read_dataflash

        return read_dataflash(path)
    if kind == "ulog":
        from .ulog import read_ulog

        return read_ulog(path)
    raise InputError(f"{path}: not an onboard log (neither DataFlash nor ULog)")


class OnboardSource:
    """Samples and events from one onboard log (decoded once, at construction)."""

    def __init__(self, path: PathLike, config: Optional[IngestConfig] = None, sysid: Optional[int] = None,
                 record: Optional[OnboardRecord] = None):
        self.path = Path(path)
        self.config = config if config is not None else IngestConfig()
        self.sysid = sysid  # an onboard log holds one vehicle; kept for the common signature
        self.record = record if record is not None else read_record(self.path)
        self.stats = IngestStats(source=str(self.path))

    def __iter__(self) -> Iterator[object]:
        self.stats = IngestStats(source=str(self.path))
        return _Builder(self.record, self.config, self.stats).samples()

    def runs(self) -> Iterator[object]:
        """The same stream as iterating the source, but each stretch of
        consecutive IMU samples as one :class:`~.imurun.ImuRun` (for
        :func:`mavnav.pipeline.run`; the same stats)."""
        self.stats = IngestStats(source=str(self.path))
        return _Builder(self.record, self.config, self.stats).samples(runs=True)


class _Builder:
    def __init__(self, rec: OnboardRecord, cfg: IngestConfig, stats: IngestStats):
        self.rec = rec
        self.cfg = cfg
        self.stats = stats
        self.cols: List[tuple] = []  # (t_us array, tag, payload arrays...)
        self.refs: List[ReferenceSet] = []

    # ------------------------------------------------------------------ attitude

    def _down_rows(self, t_us: np.ndarray):
        """Interpolated 'down' rows at ``t_us`` and whether an attitude was near enough."""
        att = self.rec.attitude
        n = t_us.size
        if att is None or att.t_us.size == 0:
            return np.zeros((n, 3)), np.zeros(n, dtype=bool)
        w, x, y, z = (att.q[:, i] for i in range(4))
        norm = np.sqrt(w * w + x * x + y * y + z * z)
        norm[norm == 0] = np.nan
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
        rows = np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        ta = att.t_us.astype(float)
        tq = t_us.astype(float)
        d = np.column_stack([np.interp(tq, ta, rows[:, k]) for k in range(3)])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        j = np.searchsorted(att.t_us, t_us)
        before = np.abs(t_us - att.t_us[np.clip(j - 1, 0, ta.size - 1)])
        after = np.abs(att.t_us[np.clip(j, 0, ta.size - 1)] - t_us)
        near = np.minimum(before, after) <= self.cfg.attitude_max_age_s * 1e6
        inside = (t_us >= att.t_us[0]) & (t_us <= att.t_us[-1])
        ok = (inside | near) & np.isfinite(d).all(axis=1)
        return d, ok

    # ------------------------------------------------------------------ streams

    def _imu(self) -> None:
        imu = self.rec.imu
        if imu is None or imu.t_us.size == 0:
            return
        d, ok = self._down_rows(imu.t_us)
        f_up = -(d[:, 0] * imu.fx_mps2 + d[:, 1] * imu.fy_mps2 + d[:, 2] * imu.fz_mps2)
        big = np.maximum(np.abs(imu.fx_mps2), np.maximum(np.abs(imu.fy_mps2), np.abs(imu.fz_mps2))) > MAX_SPECIFIC_FORCE_MPS2
        good = ok & ~big
        self.stats.imu_source = imu.name
        self.cols.append((imu.t_us[good], _IMU, f_up[good]))
        if (~ok).any():
            self.cols.append((imu.t_us[~ok], _IMU_REJ, np.zeros(int((~ok).sum()))))
            self.stats.rejected["no_attitude"] += int((~ok).sum())
        if big.any():
            self.stats.rejected["impossible"] += int((big & ok).sum())

    def _baro(self) -> Optional[np.ndarray]:
        """Baro heights (for the stuck-rangefinder rule too), or None."""
        b = self.rec.baro
        if b is None or b.t_us.size == 0:
            return None
        good = (b.pressure_pa > 0) & (b.pressure_pa < 2.0e7)
        if (~good).any():
            self.stats.rejected["impossible"] += int((~good).sum())
        t, p = b.t_us[good], b.pressure_pa[good]
        if t.size == 0:
            return None
        rc = self.cfg.baro_reference
        if rc.source == "config":
            p_ref, origin = float(rc.value), "config"
        else:
            first = p[t - t[0] <= rc.startup_window_s * 1e6]
            p_ref, origin = float(first.mean()), "startup"
        h = heights_from_pressures_m(p, p_ref)
        self.refs.append(ReferenceSet(int(t[0]), int(t[0]) * 1e-6, 0, "baro", p_ref, None, origin))
        self.stats.references["baro"] = ReferenceRecord(p_ref, origin, None)
        self.cols.append((t, _BARO, h, p))
        return np.vstack([t.astype(float), h])

    def _gnss(self) -> Optional[float]:
        """GNSS samples; returns the GNSS reference altitude (MSL) when there is one."""
        g = self.rec.gnss
        rc = self.cfg.gnss_reference
        ref = None
        origin = None
        if rc.source == "config":
            ref, origin = float(rc.value), "config"
        elif rc.source == "home" and self.rec.home_alt_msl_m is not None:
            ref, origin = float(self.rec.home_alt_msl_m), "home"
        if g is None or g.t_us.size == 0:
            if ref is not None:
                self.stats.references["gnss"] = ReferenceRecord(ref, origin, ref)
            return ref
        fixed = g.fix_type >= self.cfg.min_fix_type
        if (~fixed).any():
            self.stats.filtered["gnss_no_fix"] += int((~fixed).sum())
        t, alt, sig, fix, sats = g.t_us[fixed], g.alt_msl_m[fixed], g.sigma_m[fixed], g.fix_type[fixed], g.satellites[fixed]
        vz = g.vel_up_mps[fixed] if g.vel_up_mps is not None else np.full(t.size, np.nan)
        if self.cfg.gnss_altitude == "ellipsoid":
            self.stats.filtered["gnss_ellipsoid_not_logged"] += 1
        if t.size == 0:
            return ref
        if ref is None:
            first = alt[t - t[0] <= rc.startup_window_s * 1e6]
            ref, origin = float(first.mean()), "startup"
        self.refs.append(ReferenceSet(int(t[0]), int(t[0]) * 1e-6, 0, "gnss", ref, ref, origin))
        self.stats.references["gnss"] = ReferenceRecord(ref, origin, ref)
        self.cols.append((t, _GNSS, alt - ref, alt, sig, fix, sats, vz))
        return ref

    def _range(self, baro: Optional[np.ndarray]) -> None:
        r = self.rec.rangefinder
        if r is None or r.t_us.size == 0:
            return
        cfg = self.cfg
        self.stats.range_source = r.name
        lo = np.where(np.isfinite(r.min_m), r.min_m, cfg.rangefinder_min_m)
        hi = np.where(np.isfinite(r.max_m), r.max_m, cfg.rangefinder_max_m)
        d, att_ok = self._down_rows(r.t_us)
        c = d[:, 2]
        why = np.zeros(r.t_us.size, dtype=np.int8)  # 0 ok; codes below
        why[~r.valid] = 1
        why[(why == 0) & ~((r.range_m >= lo) & (r.range_m <= hi))] = 2
        why[(why == 0) & _stuck(r.t_us, r.range_m, baro, cfg)] = 3
        why[(why == 0) & ~att_ok] = 4
        why[(why == 0) & (c < math.cos(math.radians(cfg.rangefinder_max_tilt_deg)))] = 5
        ok = why == 0
        self.cols.append((r.t_us[ok], _RANGE, r.range_m[ok] * c[ok], r.range_m[ok], lo[ok], hi[ok]))
        bad = ~ok
        if bad.any():
            self.cols.append((r.t_us[bad], _RANGE_REJ, why[bad], r.range_m[bad], lo[bad], hi[bad], c[bad]))
            for code, kind in _RANGE_WHY.items():
                n = int((why == code).sum())
                if n:
                    self.stats.rejected[kind] += n

    def _autopilot(self, gnss_ref_msl: Optional[float]) -> None:
        a = self.rec.autopilot
        if a is None or a.t_us.size == 0:
            return
        self.stats.autopilot_source = a.name
        datum_alt = self.rec.origin_alt_msl_m if a.datum == "ekf_origin" else self.rec.home_alt_msl_m
        if gnss_ref_msl is not None and datum_alt is not None:
            h = a.height_up_m + (datum_alt - gnss_ref_msl)
            self.stats.autopilot_reference = "gnss_reference"
        else:
            h = a.height_up_m
            self.stats.autopilot_reference = "ekf_origin" if a.datum == "ekf_origin" else "autopilot_home"
        vel = a.vel_up_mps if a.vel_up_mps is not None else np.full(a.t_us.size, np.nan)
        self.cols.append((a.t_us, _AP, h, vel))

    def _tie_baro_reference(self) -> None:
        """Mark a start-up baro reference as taken at the datum when the
        autopilot's height above its reference point stays within
        ``at_datum_max_m`` over the reference's window (the log starts on the
        ground at home). Without the autopilot's height it is not known."""
        rc = self.cfg.baro_reference
        ap = next((c for c in self.cols if c[1] == _AP), None)
        for k, r in enumerate(self.refs):
            if r.kind != "baro" or r.origin != "startup" or ap is None:
                continue
            t, h = ap[0], ap[2]
            win = (t >= r.t_us) & (t <= r.t_us + rc.startup_window_s * 1e6)
            if win.any() and bool(np.all(np.abs(h[win]) <= rc.at_datum_max_m)):
                self.refs[k] = dataclasses.replace(r, at_datum=True)

    # ------------------------------------------------------------------ merge

    def samples(self, runs: bool = False) -> Iterator[object]:
        """Every sample and event in order; with ``runs``, each stretch of
        consecutive IMU samples as one :class:`~.imurun.ImuRun`."""
        st = self.stats
        self._columns()
        if not self.cols:
            st.duration_s = 0.0
            return
        t0_us, tags, idx, verdicts, gaps, run_len = self._merged_order(runs)
        by_tag = {c[1]: [a.tolist() if hasattr(a, "tolist") else a for a in c] for c in self.cols}
        if st.not_applicable:
            st.events["Notice"] += 1
            yield Notice(t0_us * 1e-6, "not_applicable", notice_text(st.not_applicable))
        yield from self.refs
        st.events["ReferenceSet"] += len(self.refs)
        # without runs every item is a sample of its own (a run length of 0)
        yield from self._with_runs(tags, idx, verdicts, gaps, run_len if run_len is not None else repeat(0),
                                   by_tag, self._sample_makers())

    def _with_runs(self, tags, idx, verdicts, gaps, run_len, by_tag, make) -> Iterator[object]:
        """:meth:`samples`' loop, with each run of IMU samples as one
        :class:`~.imurun.ImuRun`; every other item as that loop makes it.
        The lists hold the merged items outside runs and the first item of
        each run, whose ``run_len`` is the run's length (0: not a run; all 0
        when the samples are read one at a time)."""
        st = self.stats
        samples = st.samples
        imu = by_tag.get(_IMU)
        imu_name = self.rec.imu.name if self.rec.imu is not None else ""
        # the IMU columns as arrays too (contiguous, writable, int64 and float64: the
        # builder's kernel takes views of them; a copy only where they are not so already)
        imu_t = imu_f = None
        if imu is not None:
            col = next(c for c in self.cols if c[1] == _IMU)
            imu_t, imu_f = np.require(col[0], np.int64, "CW"), np.require(col[2], np.float64, "CW")
        for tag, i, verdict, gap_s, m in zip(tags, idx, verdicts, gaps, run_len):
            if m:
                if gap_s > 0.0:
                    t = imu[0][i]
                    st.gaps.append(GapRecord(IMU_STREAM, t, 0, gap_s))
                    st.events["Gap"] += 1
                    yield Gap(t_us=t, recv_s=t * 1e-6, boot=0, kind=IMU_STREAM, length_s=gap_s)
                samples[IMU_STREAM] += m
                yield ImuRun(imu[0], imu[2], i, i + m, imu_name, imu_t, imu_f)
                continue
            c = by_tag[tag]
            t = c[0][i]
            recv = t * 1e-6
            if tag not in make:  # _RANGE_REJ, _IMU_REJ
                st.events["Rejected"] += 1
                yield self._rejected(tag, c, i, t, recv)
                continue
            kind, s = make[tag](t, recv, c, i)
            if verdict:  # cannot happen after the decoder's sort; kept as the tlog rule
                st.rejected[_VERDICT[verdict]] += 1
                continue
            if gap_s > 0.0:
                st.gaps.append(GapRecord(kind, t, 0, gap_s))
                st.events["Gap"] += 1
                yield Gap(t_us=t, recv_s=recv, boot=0, kind=kind, length_s=gap_s)
            samples[kind] += 1
            yield s

    def _columns(self) -> None:
        """Decode every series into ``self.cols`` (and the references into
        ``self.refs``); the log's description into the stats."""
        rec, st = self.rec, self.stats
        st.vehicle = VehicleInfo(sysid=1)
        st.format = rec.format
        st.firmware = rec.firmware
        st.vehicle_kind = rec.vehicle
        st.not_applicable = not_applicable_reason(kind=rec.vehicle) or ""
        self._imu()
        ref = None
        if not st.not_applicable:
            baro = self._baro()
            ref = self._gnss()
            self._range(baro)
        self._autopilot(ref)
        self._tie_baro_reference()
        st.messages = dict(sorted(rec.messages.items()))
        st.bytes_read = rec.bytes_read
        st.damage = list(rec.damage)
        st.missing = rec.missing()

    def _merged_order(self, runs: bool = False) -> tuple:
        """Every column's items merged by time (ties by tag): ``(first time (us),
        tags, indices, verdicts, gaps, run lengths)``, the middle four in that
        order, as lists; the duration and rates into the stats. With ``runs``,
        the lists hold only the items outside runs of IMU samples (see
        :func:`_imu_runs`) and the first of each run, with its length in the
        last list (0: not a run); else that list is None."""
        st = self.stats
        ts = np.concatenate([c[0] for c in self.cols])
        tags = np.concatenate([np.full(c[0].size, c[1], dtype=np.int8) for c in self.cols])
        idx = np.concatenate([np.arange(c[0].size) for c in self.cols])
        order = np.lexsort((tags, ts))
        # the KindGuard rule per kind, over that kind's items in merged order
        ts_o, tags_o = ts[order].astype(np.int64), tags[order]
        verdicts_a, gaps_a = np.zeros(ts_o.size, dtype=np.int8), np.zeros(ts_o.size)
        for tag in _KIND:
            sel = np.flatnonzero(tags_o == tag)
            if sel.size:
                verdicts_a[sel], gaps_a[sel] = _guard_series(ts_o[sel], float(self.cfg.gap_min_s * 1e6),
                                                             float(self.cfg.gap_factor))
        t0, t1 = int(ts.min()), int(ts.max())
        st.duration_s = (t1 - t0) / 1e6
        dur = st.duration_s
        st.rates_hz = {k: (v / dur if dur > 0 else 0.0) for k, v in st.messages.items()}
        idx_o = idx[order]
        if not runs:
            return t0, tags_o.tolist(), idx_o.tolist(), verdicts_a.tolist(), gaps_a.tolist(), None
        run_len = _imu_runs(tags_o, idx_o, verdicts_a, gaps_a)
        inside = np.zeros(run_len.size + 1, dtype=np.int64)  # +1 from a run's start, -1 after its end
        starts = np.flatnonzero(run_len)
        inside[starts] += 1
        inside[starts + run_len[starts]] -= 1
        keep = (np.cumsum(inside[:-1]) == 0) | (run_len > 0)
        return (t0, tags_o[keep].tolist(), idx_o[keep].tolist(), verdicts_a[keep].tolist(), gaps_a[keep].tolist(),
                run_len[keep].tolist())

    def _sample_makers(self) -> dict:
        """Per sample tag, ``(t, recv, column, i) -> (kind, sample)``."""
        rec = self.rec
        imu_name = rec.imu.name if rec.imu is not None else ""
        rng_name = rec.rangefinder.name if rec.rangefinder is not None else ""
        ap_name = rec.autopilot.name if rec.autopilot is not None else ""
        baro_inst = rec.baro.instance + 1 if rec.baro is not None else 1

        def gnss(t, recv, c, i):
            sig, vz = c[4][i], c[7][i]
            return GNSS_STREAM, GnssHeight(t, recv, 0, c[2][i], c[3][i], sig if sig == sig else None, c[5][i], c[6][i],
                                      vz if vz == vz else None)

        return {
            _IMU: lambda t, recv, c, i: (IMU_STREAM, SpecificForceUp(t, recv, 0, c[2][i], imu_name)),
            _BARO: lambda t, recv, c, i: (BARO_STREAM, BaroHeight(t, recv, 0, c[2][i], c[3][i], baro_inst)),
            _GNSS: gnss,
            _RANGE: lambda t, recv, c, i: (RANGE_STREAM, RangeHeight(t, recv, 0, c[2][i], c[3][i], rng_name, c[4][i],
                                                                c[5][i])),
            _AP: lambda t, recv, c, i: (AUTOPILOT_STREAM, AutopilotHeight(t, recv, 0, c[2][i], ap_name, c[3][i])),
        }

    def _rejected(self, tag: int, c: list, i: int, t: int, recv: float) -> Rejected:
        """The refusal of a rangefinder reading (``_RANGE_REJ``) or of an IMU sample without attitude."""
        rec = self.rec
        if tag == _RANGE_REJ:
            rng_name = rec.rangefinder.name if rec.rangefinder is not None else ""
            code, rng, lo, hi, cos_t = c[2][i], c[3][i], c[4][i], c[5][i], c[6][i]
            return Rejected(recv, _RANGE_WHY[code], _range_detail(rng_name, code, rng, lo, hi, cos_t, self.cfg),
                            t, 0, sensor=RANGE_STREAM, value_m=rng, min_m=lo, max_m=hi,
                            cos_tilt=cos_t if code == 2 else math.nan)
        imu_name = rec.imu.name if rec.imu is not None else ""
        return Rejected(recv, "no_attitude", f"{imu_name}: no attitude within {self.cfg.attitude_max_age_s} s", t, 0,
                        sensor=IMU_STREAM)


def _imu_runs(tags: np.ndarray, idx: np.ndarray, verdicts: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """Per merged position, the length of the run of IMU samples that starts
    there (0: none): consecutive ``_IMU`` items that the guard passed, a new
    run at each gap (its :class:`~mavnav.samples.Gap` comes first). A run's
    column indices are consecutive (the merge is stable, the IMU column in
    time order); a position where they would not be is left to the
    per-sample loop."""
    n = tags.size
    out = np.zeros(n, dtype=np.int64)
    ok = (tags == _IMU) & (verdicts == 0)
    if not ok.any():
        return out
    start = ok.copy()
    start[1:] &= ~ok[:-1] | (gaps[1:] > 0.0)
    s = np.flatnonzero(start)
    brk = np.flatnonzero(~ok | start)
    brk = np.append(brk, n)
    e = brk[np.searchsorted(brk, s, side="right")]
    contiguous = idx[e - 1] - idx[s] == e - 1 - s
    out[s[contiguous]] = (e - s)[contiguous]
    return out


@njit(cache=True)
def _guard_series(t_us, gap_min_us, gap_factor):  # pragma: no cover - compiled
    """:meth:`~..streams.KindGuard.check` over one kind's times in order, at
    once: per item 0 ok, 1 duplicate, 2 out of order, and the gap (s) before
    it (0: none). The same arithmetic; ``tests/test_ingest_onboard_source.py``
    checks the two agree."""
    n = t_us.size
    verdict = np.zeros(n, dtype=np.int8)
    gap_s = np.zeros(n)
    last = 0
    avg = 0.0
    have_avg = False
    for i in range(n):
        t = t_us[i]
        if i == 0:
            last = t
            continue
        if t <= last:
            verdict[i] = 1 if t == last else 2
            continue
        dt = t - last
        last = t
        if have_avg and dt > max(gap_min_us, gap_factor * avg):
            gap_s[i] = dt / 1e6
            continue
        avg = dt if not have_avg else avg + 0.1 * (dt - avg)
        have_avg = True
    return verdict, gap_s


_RANGE_WHY = {1: "invalid_status", 2: "out_of_range", 3: "stuck", 4: "no_attitude", 5: "tilt"}


def _range_detail(name, code, rng, lo, hi, cos_t, cfg) -> str:
    if code == 1:
        return f"{name} {rng:.3f} m flagged invalid by the autopilot"
    if code == 2:
        return f"{name} {rng:.3f} m outside [{lo:g}, {hi:g}] m"
    if code == 3:
        return f"{name} reads {rng:.3f} m for {cfg.rangefinder_stuck_s} s while the baro moved"
    if code == 4:
        return f"{name}: no attitude for tilt correction"
    return f"{name}: tilted {math.degrees(math.acos(max(-1.0, min(1.0, cos_t)))):.0f} deg"


def _stuck(t_us: np.ndarray, rng: np.ndarray, baro: Optional[np.ndarray], cfg: IngestConfig) -> np.ndarray:
    """The tlog rule: one raw value for ``rangefinder_stuck_s`` while the baro height moved
    at least ``rangefinder_stuck_min_move_m``; the run's later readings are stuck."""
    out = np.zeros(t_us.size, dtype=bool)
    if baro is None or t_us.size == 0:
        return out
    hb = np.interp(t_us.astype(float), baro[0], baro[1])
    stuck_us = cfg.rangefinder_stuck_s * 1e6
    start = 0
    lo = hi = hb[0]
    for i in range(1, t_us.size):
        if rng[i] != rng[start]:
            start = i
            lo = hi = hb[i]
            continue
        lo = min(lo, hb[i])
        hi = max(hi, hb[i])
        if t_us[i] - t_us[start] >= stuck_us and hi - lo >= cfg.rangefinder_stuck_min_move_m:
            out[i] = True
    return out


__all__ = ["OnboardSource", "read_record", "detect_onboard"]
