"""The ICAO-style profiles in config/ load, and the protection level against
their alert limits decides availability as it should."""

from __future__ import annotations


import pytest

from mavnav.audit import audit_file
from mavnav.config import load_config
from tests.support.paths import CONFIG, SITL_LOGS

LOG = SITL_LOGS / "px4_landing_nominal.tlog"  # nominal: only the profile differs


@pytest.mark.parametrize("name, limit", [("profile_cat1.yaml", 10.0), ("profile_cat2_3.yaml", 5.3),
                                         ("profile_small_drone.yaml", 4.0)])
def test_profiles_load(name, limit):
    cfg = load_config(CONFIG / name)
    assert cfg.monitor.alert_limit_m == limit and cfg.monitor.time_to_alarm_s == 1.0


def test_stricter_profile_is_unavailable_more_often():
    """Same nominal flight: the CAT II/III integrity risk (5e-9) needs a larger k than
    CAT I (1e-6) against a smaller alert limit, so integrity is available less:
    strictly, on a flight where the protection level comes between the two limits."""
    cat1 = audit_file(LOG, load_config(CONFIG / "profile_cat1.yaml"))["availability"]["overall"]
    cat23 = audit_file(LOG, load_config(CONFIG / "profile_cat2_3.yaml"))["availability"]["overall"]
    assert cat23["unavailable"] > cat1["unavailable"]
    assert cat23["nominal"] + cat23["caution"] < cat1["nominal"] + cat1["caution"]
