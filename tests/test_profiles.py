"""The ICAO-style profiles in config/ load, and the protection level against
their alert limits decides availability as it should."""

from __future__ import annotations


import pytest
import yaml

from mavnav.audit import audit_file
from mavnav.config import config_from_dict, load_config
from tests.support.paths import CONFIG, SITL_LOGS

LOG = SITL_LOGS / "px4_landing_nominal.tlog"  # nominal: only the profile differs


@pytest.mark.parametrize("name, limit", [("profile_cat1.yaml", 10.0), ("profile_cat2_3.yaml", 5.3),
                                         ("profile_small_drone.yaml", 4.0)])
def test_profiles_load(name, limit):
    cfg = load_config(CONFIG / name)
    assert cfg.monitor.alert_limit_m == limit and cfg.monitor.time_to_alarm_s == 1.0


@pytest.mark.slow
def test_stricter_profile_is_unavailable_more_often():
    """Same nominal flight: the CAT II/III integrity risk (5e-9) needs a larger k than
    CAT I (1e-6) against a smaller alert limit, so integrity is available less:
    strictly, on a flight where the protection level comes between the two limits."""
    # the protection level comes between the two limits at the start, before the GNSS: where the baro is
    # the only height sensor, which by itself makes monitoring degraded (min_height_sensors); that rule is
    # set aside here so that the profiles alone differ, and so is the separation protection level, which
    # by itself makes one height sensor unprotected
    def overall(name):
        raw = yaml.safe_load((CONFIG / name).read_text())
        raw["monitor"]["min_height_sensors"] = 1
        raw["monitor"].setdefault("features", {})["separation_protection"] = False
        return audit_file(LOG, config_from_dict(raw))["availability"]["overall"]

    cat1, cat23 = overall("profile_cat1.yaml"), overall("profile_cat2_3.yaml")
    assert cat23["unavailable"] > cat1["unavailable"]
    assert cat23["nominal"] + cat23["caution"] < cat1["nominal"] + cat1["caution"]
