"""ArduPilot DataFlash (``.bin``) -> :class:`~.record.OnboardRecord`.

pymavlink's :class:`~pymavlink.DFReader.DFReader_binary` indexes the file
(every message's offset, the FMT/FMTU formats, parameters); the columns
mavnav needs are then gathered straight from the mapped bytes with numpy,
one structured view per message type, with DFReader's own format table
(``FORMAT_TO_STRUCT``: type and multiplier per format character). That is
the same decoding as ``DFReader.recv_match``, without a Python object per
message (the test suite checks the two agree).

Message and field names across ArduCopter 3.1-4.7, ArduPlane and ArduSub:

* time: ``TimeUS`` (us since boot), or ``TimeMS`` (ms) in 3.x logs; old
  GPS messages carry GPS week milliseconds in ``TimeMS`` and the boot time
  in ``T``.
* IMU: ``ACC`` (batch/fast, ``I`` instance) when it is faster than ``IMU``;
  ``IMU`` with an ``I`` column (4.x) or ``IMU``/``IMU2``/``IMU3``; old
  ``ACC1``. The first instance is used (the autopilot's primary by default).
* attitude: ``ATT`` (the active AHRS), else ``AHR2``; degrees.
* baro: ``BARO`` with ``I`` (4.x) or ``BARO``/``BAR2``/``BAR3``; the
  instance is ``BARO_PRIMARY`` (default 0), rows with ``Health`` 0 dropped.
* GNSS: ``GPS`` (``I`` 0, or no ``I``), ``Alt`` metres MSL, ``Status`` in
  MAVLink fix-type numbering; ``GPA.VAcc`` (m) matched by time and instance.
* rangefinder: ``RFND`` (``Instance``/``Dist``/``Stat``/``Orient``; or
  ``Dist1``/``Orient1``), old ``SONR`` (``DistCM``); limits from the
  ``RNGFND1_MIN_CM``/``_MAX_CM`` (or ``RNGFND1_MIN``/``_MAX`` in m) parameters.
* autopilot height: ``XKF1``/``NKF1`` (core 0; the family chosen by
  ``AHRS_EKF_TYPE``), old ``EKF1``: ``-PD`` above the EKF origin; else
  ``CTUN.Alt`` above home. Origin and home altitudes from ``ORGN`` (Type 0,
  1), else home from old GPS ``Alt - RelAlt``.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from ...errors import InputError
from .head import read_head
from .record import (
    AttitudeSeries,
    AutopilotSeries,
    BaroSeries,
    GnssSeries,
    ImuSeries,
    OnboardRecord,
    RangeSeries,
)

HEAD = b"\xa3\x95"
MAV_SENSOR_ROTATION_PITCH_270 = 25  # downward
RANGEFINDER_STATUS_GOOD = 4  # AP RangeFinder::Status::Good
ORGN_EKF_ORIGIN, ORGN_AHRS_HOME = 0, 1

_STRUCT_TO_NUMPY = {
    "b": "i1", "B": "u1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4",
    "q": "<i8", "Q": "<u8", "f": "<f4", "d": "<f8", "e": "<f2",
    "4s": "S4", "16s": "S16", "64s": "S64",
}

_VEHICLES = (("copter", "copter"), ("plane", "plane"), ("rover", "rover"), ("sub", "sub"),
             ("heli", "copter"), ("tracker", "tracker"), ("blimp", "blimp"))


def is_dataflash(head: bytes) -> bool:
    """A DataFlash log starts with an FMT record (``A3 95 80``)."""
    return head[:3] == HEAD + b"\x80"


Table = Dict[str, np.ndarray]


class _Log:
    """A DFReader index with numpy access to whole message types."""

    def __init__(self, path: str):
        from pymavlink import DFReader  # heavy import, only when a .bin is read

        self._df = DFReader
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                self.r = DFReader.DFReader_binary(path, zero_time_base=True)
        except Exception as exc:  # DFReader raises bare exceptions on broken FMT tables
            raise InputError(f"{path}: unreadable DataFlash log ({type(exc).__name__}: {exc})") from None
        self.messages_stderr = err.getvalue()
        self.buf = np.frombuffer(self.r.data_map, dtype=np.uint8)
        self.damage: List[str] = []

    def close(self) -> None:
        self.buf = None  # release the export before the mmap is closed
        with contextlib.suppress(Exception):
            self.r.data_map.close()
        with contextlib.suppress(Exception):
            self.r.filehandle.close()

    def count(self, name: str) -> int:
        mtype = self.r.name_to_id.get(name)
        return 0 if mtype is None else len(self.r.offsets[mtype])

    def columns(self, name: str) -> List[str]:
        mtype = self.r.name_to_id.get(name)
        return [] if mtype is None else list(self.r.formats[mtype].columns)

    def table(self, name: str) -> Optional[Table]:
        """Every record of message ``name`` as columns (DFReader's multipliers applied)."""
        r = self.r
        mtype = r.name_to_id.get(name)
        if mtype is None or not r.offsets[mtype]:
            return None
        fmt = r.formats[mtype]
        fields = []
        mults = []
        for col, ch in zip(fmt.columns, fmt.format):
            code, mult, _typ = self._df.FORMAT_TO_STRUCT[ch]
            if code not in _STRUCT_TO_NUMPY:
                return None
            fields.append((col, _STRUCT_TO_NUMPY[code]))
            mults.append(mult)
        dtype = np.dtype(fields)
        body = fmt.len - 3
        if dtype.itemsize != body:
            self.damage.append(f"{name}: format {fmt.format} does not fill its {fmt.len}-byte record; skipped")
            return None
        offs = np.asarray(r.offsets[mtype], dtype=np.int64) + 3
        whole = offs + body <= self.buf.size
        if not whole.all():
            self.damage.append(f"{name}: {int((~whole).sum())} record(s) cut off at the end of the file")
            offs = offs[whole]
        rows = self.buf[offs[:, None] + np.arange(body, dtype=np.int64)]
        arr = rows.view(dtype).reshape(-1)
        out: Table = {}
        for (col, _), mult in zip(fields, mults):
            v = arr[col]
            out[col] = v * mult if mult is not None else v
        return out

    def time_us(self, name: str, t: Table) -> Optional[np.ndarray]:
        cols = t.keys()
        if "T" in cols and ("Week" in cols or "GWk" in cols):  # old GPS: TimeMS is GPS time of week
            return t["T"].astype(np.int64) * 1000
        if "TimeUS" in cols:
            return t["TimeUS"].astype(np.int64)
        if "TimeMS" in cols:
            return t["TimeMS"].astype(np.int64) * 1000
        self.damage.append(f"{name}: no boot time field; not used")
        return None

    def timed(self, name: str, field: str) -> Optional[tuple[Table, np.ndarray]]:
        """``(columns, boot time in us)`` of message ``name`` when it is logged with ``field``."""
        t = self.table(name)
        if t is None or field not in t:
            return None
        tt = self.time_us(name, t)
        return None if tt is None else (t, tt)

    def param(self, name: str) -> Optional[float]:
        v = self.r.params.get(name)
        try:
            return None if v is None else float(v)
        except (TypeError, ValueError):
            return None


def _instance(t: Table, key: str, which: int) -> np.ndarray:
    return t[key] == which if key in t else np.ones(len(next(iter(t.values()))), dtype=bool)


def _sorted(t_us: np.ndarray, *cols: np.ndarray, what: str, damage: List[str]):
    """Sort by time, keep the first of equal times, drop non-finite rows; say what was dropped."""
    good = np.ones(t_us.size, dtype=bool)
    for c in cols:
        if c.dtype.kind == "f":
            good &= np.isfinite(c)
    nonfinite = int((~good).sum())
    order = np.argsort(t_us[good], kind="stable")
    t = t_us[good][order]
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = t[1:] > t[:-1]
    backwards = int(np.count_nonzero(np.diff(t_us[good]) < 0)) if t_us.size > 1 else 0
    if nonfinite:
        damage.append(f"{what}: {nonfinite} record(s) with non-finite values dropped")
    if backwards:
        damage.append(f"{what}: time went backwards {backwards} time(s); records re-ordered")
    if int((~keep).sum()):
        damage.append(f"{what}: {int((~keep).sum())} record(s) repeating a time dropped")
    return (t[keep],) + tuple(c[good][order][keep] for c in cols)


def _quat_from_euler_deg(roll, pitch, yaw) -> np.ndarray:
    r, p, y = (np.radians(np.asarray(a, dtype=float)) / 2 for a in (roll, pitch, yaw))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.column_stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ])


def read_dataflash(path) -> OnboardRecord:
    """Decode one DataFlash log. :class:`InputError` if it is not one at all."""
    path = str(path)
    if not is_dataflash(read_head(path, 3)):
        raise InputError(f"{path}: not an ArduPilot DataFlash log (no FMT record at the start)")
    log = _Log(path)
    try:
        return _decode(log, path)
    finally:
        log.close()


def _decode(log: _Log, path: str) -> OnboardRecord:
    r = log.r
    rec = OnboardRecord(path=path, format="dataflash", bytes_read=os.path.getsize(path))
    rec.messages = {r.id_to_name[i]: len(r.offsets[i]) for i in range(256)
                    if r.offsets[i] and i in r.id_to_name}
    _firmware(log, rec)
    rec.imu = _imu(log)
    rec.attitude = _attitude(log)
    rec.baro = _baro(log)
    rec.gnss = _gnss(log, rec)
    rec.rangefinder = _rangefinder(log)
    rec.autopilot = _autopilot(log)
    _datums(log, rec)
    _stream_damage(log, rec)
    rec.damage.extend(log.damage)
    if all(getattr(rec, k) is None for k in ("imu", "baro", "gnss", "rangefinder")):
        why = "; ".join(rec.damage) or "no IMU, baro, GNSS or rangefinder records"
        raise InputError(f"{path}: DataFlash log with nothing mavnav can use ({why})")
    return rec


def _firmware(log: _Log, rec: OnboardRecord) -> None:
    msg = log.table("MSG")
    if msg is None:
        return
    for raw in msg["Message"]:
        text = raw.split(b"\0", 1)[0].decode("ascii", "replace").strip()
        m = re.match(r"(Ardu\w+|APM:\w+)\s+V?[\d.]+\S*", text)
        if m:
            rec.firmware = m.group(0)
            low = m.group(1).lower()
            for key, kind in _VEHICLES:
                if key in low:
                    rec.vehicle = kind
                    break
            return


def _imu(log: _Log) -> Optional[ImuSeries]:
    cands = []
    for name in ("ACC", "IMU", "ACC1"):
        got = log.timed(name, "AccX")
        if got is None:
            continue
        t, tt = got
        sel = _instance(t, "I", 0)
        if name == "ACC" and "SampleUS" in t:
            tt = t["SampleUS"].astype(np.int64)  # the sample's own time
        cands.append((name, tt[sel], t["AccX"][sel], t["AccY"][sel], t["AccZ"][sel]))
    if not cands:
        return None

    def rate(c):
        tt = c[1]
        return (tt.size - 1) / ((tt.max() - tt.min()) * 1e-6) if tt.size > 1 and tt.max() > tt.min() else 0.0

    name, tt, ax, ay, az = max(cands, key=rate)
    t, fx, fy, fz = _sorted(tt, ax.astype(float), ay.astype(float), az.astype(float), what=name, damage=log.damage)
    return ImuSeries(name, t, fx, fy, fz)


def _attitude(log: _Log) -> Optional[AttitudeSeries]:
    for name in ("ATT", "AHR2"):
        got = log.timed(name, "Roll")
        if got is None:
            continue
        t, tt = got
        t_us, roll, pitch, yaw = _sorted(tt, t["Roll"].astype(float), t["Pitch"].astype(float),
                                         t["Yaw"].astype(float), what=name, damage=log.damage)
        return AttitudeSeries(name, t_us, _quat_from_euler_deg(roll, pitch, yaw))
    return None


def _baro(log: _Log) -> Optional[BaroSeries]:
    primary = int(log.param("BARO_PRIMARY") or 0)
    t = log.table("BARO")
    if t is None:
        return None
    if "I" in t:
        instances = sorted(set(int(i) for i in np.unique(t["I"])))
        parts = {i: (t, t["I"] == i) for i in instances}
    else:
        parts = {0: (t, np.ones(t["Press"].size, dtype=bool))}
        for i, name in ((1, "BAR2"), (2, "BAR3")):
            ti = log.table(name)
            if ti is not None and "Press" in ti:
                parts[i] = (ti, np.ones(ti["Press"].size, dtype=bool))
    inst = primary if primary in parts else min(parts)
    tb, sel = parts[inst]
    name = f"BARO[{inst}]"
    if "Health" in tb:
        unhealthy = sel & (tb["Health"] == 0)
        if unhealthy.any():
            log.damage.append(f"{name}: {int(unhealthy.sum())} record(s) flagged unhealthy dropped")
        sel = sel & (tb["Health"] != 0)
    tt = log.time_us("BARO", tb)
    if tt is None:
        return None
    p = tb["Press"].astype(float)[sel]
    t_us, p = _sorted(tt[sel], p, what=name, damage=log.damage)
    return BaroSeries(name, t_us, p, instance=inst, instances=len(parts))


def _gnss(log: _Log, rec: OnboardRecord) -> Optional[GnssSeries]:
    got = log.timed("GPS", "Alt")
    if got is None:
        return None
    t, tt = got
    sel = _instance(t, "I", 0)
    tt = tt[sel]
    alt = t["Alt"].astype(float)[sel]
    fix = t["Status"].astype(np.int64)[sel]
    sats = t["NSats"].astype(np.int64)[sel]
    sigma = np.full(tt.size, np.nan)
    # GPS.VZ is the receiver's vertical velocity, NED (down positive), in every
    # ArduPilot version here; a receiver without it reports 0 and says so in GPA.VV
    vel_up = -t["VZ"].astype(float)[sel] if "VZ" in t else np.full(tt.size, np.nan)
    gpa = log.table("GPA")
    if gpa is not None and "VAcc" in gpa:
        gt = log.time_us("GPA", gpa)
        if gt is not None:
            gsel = _instance(gpa, "I", 0)
            gt, vacc = gt[gsel], gpa["VAcc"].astype(float)[gsel]
            if gt.size:
                order = np.argsort(gt, kind="stable")
                gt, vacc = gt[order], vacc[order]
                j = np.clip(np.searchsorted(gt, tt), 0, gt.size - 1)
                jm = np.clip(j - 1, 0, gt.size - 1)
                near = np.where(np.abs(gt[jm] - tt) < np.abs(gt[j] - tt), jm, j)
                ok = np.abs(gt[near] - tt) <= 100_000  # GPA is logged beside its GPS record
                sigma = np.where(ok & (vacc[near] > 0), vacc[near], np.nan)
                if "VV" in gpa:
                    vv = gpa["VV"].astype(float)[gsel][order]
                    vel_up = np.where(ok & (vv[near] == 0), np.nan, vel_up)
    if "RelAlt" in t and fix.size:  # old logs: home altitude = Alt - RelAlt at a 3D fix
        good = fix >= 3
        if good.any():
            rel = t["RelAlt"].astype(float)[sel]
            rec.home_alt_msl_m = float(np.median((alt - rel)[good]))
    # Keep NaN sigma through the finite-row filter: sort without it, then reattach.
    order_t, alt2, fix2, sats2, idx = _sorted(tt, alt, fix, sats, np.arange(tt.size), what="GPS[0]", damage=log.damage)
    return GnssSeries("GPS[0]", order_t, alt2, sigma[idx], fix2, sats2, vel_up[idx])


def _range_limits(log: _Log):
    lo = log.param("RNGFND1_MIN_CM")
    hi = log.param("RNGFND1_MAX_CM")
    if lo is not None or hi is not None:
        return (lo / 100.0 if lo is not None else math.nan), (hi / 100.0 if hi is not None else math.nan)
    lo, hi = log.param("RNGFND1_MIN"), log.param("RNGFND1_MAX")  # metres in ArduPilot 4.6+
    return (lo if lo is not None else math.nan), (hi if hi is not None else math.nan)


def _rangefinder(log: _Log) -> Optional[RangeSeries]:
    lo, hi = _range_limits(log)
    t = log.table("RFND")
    name = None
    if t is not None:
        tt = log.time_us("RFND", t)
        if tt is None:
            return None
        if "Dist" in t:  # 4.x: one record per instance
            inst = t["Instance"] if "Instance" in t else np.zeros(tt.size)
            down = t["Orient"] == MAV_SENSOR_ROTATION_PITCH_270 if "Orient" in t else np.ones(tt.size, dtype=bool)
            cand = [int(i) for i in np.unique(inst[down])]
            if not cand:
                return None
            which = cand[0]
            sel = down & (inst == which)
            dist = t["Dist"].astype(float)[sel]
            valid = (t["Stat"][sel] == RANGEFINDER_STATUS_GOOD) if "Stat" in t else np.ones(dist.size, dtype=bool)
            tt = tt[sel]
            name = f"RFND[{which}]"
        else:  # 3.4-3.6: Dist1 (+ Orient1)
            sel = (t["Orient1"] == MAV_SENSOR_ROTATION_PITCH_270) if "Orient1" in t else np.ones(tt.size, dtype=bool)
            if not sel.any():
                return None
            dist = t["Dist1"].astype(float)[sel]
            valid = np.ones(dist.size, dtype=bool)
            tt = tt[sel]
            name = "RFND[0]"
    else:
        got = log.timed("SONR", "DistCM")
        if got is None:
            return None
        t, tt = got
        dist = t["DistCM"].astype(float) / 100.0
        valid = np.ones(dist.size, dtype=bool)
        name = "SONR"
    t_us, dist, valid = _sorted(tt, dist, valid, what=name, damage=log.damage)
    n = t_us.size
    return RangeSeries(name, t_us, dist, np.full(n, lo), np.full(n, hi), valid.astype(bool))


def _autopilot(log: _Log) -> Optional[AutopilotSeries]:
    ekf = log.param("AHRS_EKF_TYPE")
    order = ["XKF1", "NKF1", "EKF1", "CTUN"]
    if ekf == 2:
        order = ["NKF1", "XKF1", "EKF1", "CTUN"]
    if log.param("AHRS_EKF_USE") == 0:
        # ArduCopter 3.2-3.3 flying on its inertial navigation: the EKF ran
        # beside it unused (and diverged on some logs); CTUN is what it flew on
        order = ["CTUN"] + order[:-1]
    for name in order:
        series = _ctun(log) if name == "CTUN" else _ekf_height(log, name)
        if series is not None:
            return series
    return None


def _ekf_height(log: _Log, name: str) -> Optional[AutopilotSeries]:
    got = log.timed(name, "PD")
    if got is None:
        return None
    t, tt = got
    sel = _instance(t, "C", 0)
    vel = _optional_velocity(t, "VD", -1.0, sel)
    t_us, up, vel = _sorted(tt[sel], -t["PD"].astype(float)[sel], vel, what=name, damage=log.damage)
    return AutopilotSeries(name, t_us, up, "ekf_origin", _unmask(vel))


def _ctun(log: _Log) -> Optional[AutopilotSeries]:
    got = log.timed("CTUN", "Alt")
    if got is None:
        return None
    t, tt = got
    sel = np.ones(tt.size, dtype=bool)
    vel = _optional_velocity(t, "CRt", 0.01, sel) if "CRt" in t else _optional_velocity(t, "CRate", 0.01, sel)
    t_us, up, vel = _sorted(tt, t["Alt"].astype(float), vel, what="CTUN", damage=log.damage)
    return AutopilotSeries("CTUN", t_us, up, "home", _unmask(vel))


_NO_VALUE = 1e300  # stands for "not logged" through _sorted, which drops non-finite rows


def _optional_velocity(t: dict, field: str, scale: float, sel: np.ndarray) -> np.ndarray:
    """``field * scale`` (up, m/s) where logged and finite, else a marker that _unmask turns to NaN."""
    if field not in t:
        return np.full(int(sel.sum()), _NO_VALUE)
    v = t[field].astype(float)[sel] * scale
    return np.where(np.isfinite(v), v, _NO_VALUE)


def _unmask(v: np.ndarray) -> np.ndarray:
    return np.where(v == _NO_VALUE, np.nan, v)


def _datums(log: _Log, rec: OnboardRecord) -> None:
    t = log.table("ORGN")
    if t is None or "Alt" not in t:
        return
    kind = t["Type"] if "Type" in t else np.zeros(t["Alt"].size)
    alt = t["Alt"].astype(float)
    origin = alt[kind == ORGN_EKF_ORIGIN]
    home = alt[kind == ORGN_AHRS_HOME]
    if origin.size:
        rec.origin_alt_msl_m = float(origin[-1])
    if home.size:
        rec.home_alt_msl_m = float(home[0])  # where the vehicle armed


def _stream_damage(log: _Log, rec: OnboardRecord) -> None:
    """What DFReader's indexer reported (bad headers, unknown types, a cut tail)."""
    text = log.messages_stderr
    bad = len(re.findall(r"bad header", text))
    unknown = re.findall(r"unknown msg type 0x[0-9a-f]+ \((\d+)\) at (\d+)", text)
    if bad:
        rec.damage.append(f"{bad} corrupt byte(s) skipped between records")
    if unknown:
        rec.damage.append(f"unknown message type {unknown[0][0]} at byte {unknown[0][1]}: "
                          f"the log is read up to there")
    last = max((offs[-1] for offs in log.r.offsets if offs), default=0)
    size = log.buf.size if log.buf is not None else 0
    if size - last > 512 and not unknown:
        rec.damage.append(f"the last {size - last} bytes hold no readable record")


__all__ = ["read_dataflash", "is_dataflash"]
