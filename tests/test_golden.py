"""Behaviour unchanged: ``mavnav audit`` of every log in ``sitl_logs/`` writes
the same JSON, CSV and table, byte for byte, as the files in ``tests/golden/``
(see :mod:`tests.support.golden`; ``make golden`` rewrites them when a change
of behaviour is meant)."""

from __future__ import annotations

import pytest

from tests.support.golden import GOLDEN, LOGS, REGENERATE, SUFFIXES, audit_outputs, expected_path, first_differences

pytestmark = pytest.mark.golden


def test_every_log_has_its_expected_files_and_no_more():
    assert LOGS, "no sitl_logs/*.tlog"
    want = {expected_path(log, s).name for log in LOGS for s in SUFFIXES}
    have = {p.name for p in GOLDEN.iterdir()}
    assert have == want, (f"expected outputs missing {sorted(want - have)}, left over {sorted(have - want)}: "
                          f"{REGENERATE}")


@pytest.mark.parametrize("log", LOGS)
def test_audit_outputs_are_unchanged(log, tmp_path):
    actual = audit_outputs(log, tmp_path)
    differ = []
    for suffix in SUFFIXES:
        want = expected_path(log, suffix).read_bytes()
        if actual[suffix] != want:
            differ.append(first_differences(want, actual[suffix], expected_path(log, suffix).name))
    assert not differ, (f"the audit of sitl_logs/{log} changed; if that is meant: {REGENERATE}\n"
                        + "\n".join(differ))
