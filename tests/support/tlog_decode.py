"""Decode tlog bytes with pymavlink itself (independent of mavnav.ingest)."""

from __future__ import annotations

from pymavlink import mavutil


def decode(tmp_path, data: bytes, name: str):
    """Every message pymavlink decodes from ``data``, written to ``tmp_path/name``."""
    p = tmp_path / name
    p.write_bytes(data)
    conn = mavutil.mavlink_connection(str(p), robust_parsing=True)
    out = []
    while True:
        m = conn.recv_msg()
        if m is None:
            break
        out.append(m)
    conn.close()
    return out
