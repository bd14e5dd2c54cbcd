"""The wire layer's field reader (used by the injector for boot times): the
first named field in wire order, char arrays counted as one value, truncated
MAVLink 2 payloads zero-padded."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav2

from mavnav.ingest import wire


def _payload(msg) -> bytes:
    msg.pack(mav2.MAVLink(None), force_mavlink1=True)
    return bytes(msg.get_payload())


@pytest.mark.parametrize("msg, name, value", [
    (mav2.MAVLink_attitude_message(123456, 0.1, 0.2, 0.3, 0, 0, 0), "time_boot_ms", 123456),
    # the char array 'name' comes after the time in wire order, first in declaration order
    (mav2.MAVLink_named_value_float_message(98765, b"alt", 1.5), "time_boot_ms", 98765),
    (mav2.MAVLink_debug_vect_message(b"vec", 5_000_000, 1.0, 2.0, 3.0), "time_usec", 5_000_000),
    # HIGHRES_IMU has only time_usec
    (mav2.MAVLink_highres_imu_message(7_000_000, *([0.0] * 13), 0), "time_usec", 7_000_000),
])
def test_field_reader_finds_the_first_time_field(msg, name, value):
    got_name, read = wire.make_field_reader(msg.get_msgId(), ("time_boot_ms", "time_usec"))
    assert got_name == name
    assert read(_payload(msg)) == value


def test_field_reader_reads_after_a_char_array_and_pads_truncated_payloads():
    msg = mav2.MAVLink_named_value_float_message(1, b"speed", 2.5)
    name, read = wire.make_field_reader(msg.get_msgId(), ("value",))
    assert name == "value" and read(_payload(msg)) == 2.5
    name, read = wire.make_field_reader(msg.get_msgId(), ("time_boot_ms",))
    assert read(bytes([7])) == 7  # MAVLink 2 trailing zeros cut: padded back


def test_field_reader_is_none_without_the_field_or_the_message():
    assert wire.make_field_reader(wire.MSG_ID["HEARTBEAT"], ("time_boot_ms", "time_usec")) is None
    assert wire.make_field_reader(60000, ("time_boot_ms",)) is None
