"""The cheaper __init__ of mavnav.fastinit builds the same objects as the
one dataclasses wrote (kept as ``__reference_init__``)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from mavnav import bank, channel, report, samples
from mavnav.fastinit import fast_frozen_init
from mavnav.monitor import table, verdict

PATCHED = [samples.SpecificForceUp, samples.BaroHeight, samples.GnssHeight, samples.RangeHeight,
           samples.AutopilotHeight, samples.Rejected, report.ChannelReport, report.PairReport,
           report.SourceStatus, report.EpochReport, report.AlarmEvent, verdict.Verdict, table.Judgement,
           channel.AuxMeasurement, channel.EpochInputs, bank.BankStep]


def _values(cls, k: int) -> list:
    """A distinct value per field (types do not matter to either __init__)."""
    return [f"{f.name}-{k}" if k % 2 else (k + i) * 0.5 for i, f in enumerate(dataclasses.fields(cls))]


def _build(cls, init, args, kwargs):
    obj = object.__new__(cls)
    init(obj, *args, **kwargs)
    return obj


@pytest.mark.parametrize("cls", PATCHED, ids=lambda c: c.__name__)
def test_fast_init_builds_what_the_dataclass_init_builds(cls):
    assert cls.__init__ is not cls.__reference_init__
    fields = dataclasses.fields(cls)
    for k in range(4):
        vals = _values(cls, k)
        # all positional, all by keyword, and only the required ones (defaults filled in)
        required = [v for f, v in zip(fields, vals) if f.default is dataclasses.MISSING]
        kw = {f.name: v for f, v in zip(fields, vals)}
        for args, kwargs in ((vals, {}), ((), kw), (required, {})):
            a = cls(*args, **kwargs)
            b = _build(cls, cls.__reference_init__, args, kwargs)
            assert a == b or repr(a) == repr(b)
            assert repr(a) == repr(b)
            for f in fields:
                x, y = getattr(a, f.name), getattr(b, f.name)
                assert x is y or (x != x and y != y and math.isnan(x) and math.isnan(y))
    with pytest.raises(TypeError):
        cls()  # the required fields stay required (none of these has none)
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(cls(*_values(cls, 0)), fields[0].name, 1)


def test_replace_goes_through_the_fast_init():
    s = samples.BaroHeight(1, 2.0, 0, 3.0, 101325.0, 1)
    r = dataclasses.replace(s, height_ref_m=4.0)
    assert r == samples.BaroHeight(1, 2.0, 0, 4.0, 101325.0, 1)


def test_refuses_what_it_cannot_copy():
    @dataclasses.dataclass(frozen=True, slots=True)
    class WithFactory:
        a: list = dataclasses.field(default_factory=list)

    @dataclasses.dataclass(frozen=True)
    class NoSlots:
        a: int

    @dataclasses.dataclass(frozen=True, slots=True)
    class PostInit:
        a: int

        def __post_init__(self):
            pass

    for cls in (WithFactory, NoSlots, PostInit):
        with pytest.raises(TypeError):
            fast_frozen_init(cls)
