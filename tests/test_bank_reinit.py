"""A channel restarted as a copy of another, its level opened (ChannelBank.reinit_from):
its own sensor sets its level, the baro's reading does not hold it where the copy had it."""

from __future__ import annotations

import pytest

from mavnav.bank import BARO, GNSS, RNG, ChannelBank
from mavnav.channel import DH, AuxMeasurement, EpochInputs, Model
from mavnav.config import config_from_dict

DT_S = 0.1


def _bank() -> ChannelBank:
    bank = ChannelBank(Model.from_config(config_from_dict({})))
    bank.start(0, 0.0)
    return bank


def _hover(bank: ChannelBank, t_us: int, n: int, baro_m: float, aux: dict) -> int:
    """``n`` epochs at rest: the baro reads ``baro_m``, the aux sensors ``aux``."""
    for _ in range(n):
        t_us += int(DT_S * 1e6)
        bank.step(EpochInputs(t_us=t_us, dt_s=DT_S, dp_m=0.0, dv_mps=0.0, baro_m=baro_m,
                              gnss=(AuxMeasurement(aux["gnss"], 0.5, 0.0) if "gnss" in aux else None),
                              rng=(AuxMeasurement(aux["rng"], 0.05, 0.0) if "rng" in aux else None)))
    return t_us


@pytest.mark.parametrize("c,sensor", [(GNSS, "gnss"), (RNG, "rng")])
def test_a_restarted_channel_takes_its_level_from_its_own_sensor(c, sensor):
    bank = _bank()
    t = _hover(bank, 0, 100, 0.0, {})
    # the baro now reads 5 m high (a step inside a gap; or a roof under the
    # rangefinder: the level the aux sensor sees differs from the baro's by 5 m)
    t = _hover(bank, t, 10, 5.0, {})
    assert bank.x[BARO, 0] == pytest.approx(5.0, abs=0.5)
    bank.reinit_from(c, BARO, extra_height_var=25.0)
    p_baro_reading = bank.P[c, 0, 0] + bank.P[c, DH, DH] + 2 * bank.P[c, 0, DH]
    assert p_baro_reading == pytest.approx(bank.P[BARO, 0, 0] + bank.P[BARO, DH, DH] + 2 * bank.P[BARO, 0, DH])
    t = _hover(bank, t, 30, 5.0, {sensor: 0.0})
    # the channel went most of the way to its sensor (the GNSS shares the rest
    # with its own slow error, 4 m against the 5 m opening), and the baro's offset
    # to it moved into the channel's baro bias
    moved_m = 5.0 - bank.x[c, 0]
    assert moved_m > (2.5 if c == GNSS else 4.5)
    assert bank.x[c, DH] == pytest.approx(5.0 - bank.x[c, 0], abs=1.0)
