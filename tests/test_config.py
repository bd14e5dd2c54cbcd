"""Bad configuration is refused by name, as one line; non-finite inputs are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from mavnav.channel import AuxMeasurement, EpochInputs, Model, initial_state, step
from mavnav.config import Config, config_from_dict, load_config
from mavnav.errors import ConfigError, NonFiniteInputError


def test_defaults_load_and_are_frozen():
    cfg = load_config(None)
    assert cfg.monitor.mode == "adaptive"
    with pytest.raises(ValidationError, match="frozen"):
        cfg.filter.step_s = 1.0  # type: ignore[misc]


def test_paper_config_loads():
    cfg = load_config("config/paper_2015_covariance.yaml")
    assert cfg.sensors.gnss.sigma_z_m == 5.0 and cfg.filter.accel_noise_form == "printed"


@pytest.mark.parametrize(
    "data, needle",
    [
        ({"sensors": {"gnss": {"sigmaz_m": 2}}}, "unknown key 'sensors.gnss.sigmaz_m'"),
        ({"filtre": {}}, "unknown key 'filtre'"),
        ({"sensors": {"baro": {"sigma_bb_m": -1}}}, "sensors.baro.sigma_bb_m"),
        ({"filter": {"accel_noise_form": "exact"}}, "filter.accel_noise_form"),
        ({"sensors": {"ins": {"sigma_a_mps2": "lots"}}}, "sensors.ins.sigma_a_mps2"),
        ({"ingest": {"baro_reference": {"source": "config"}}}, "needs a value"),
    ],
)
def test_wrong_config_is_refused_by_name(data, needle):
    with pytest.raises(ConfigError) as exc:
        config_from_dict(data, origin="x.yaml")
    msg = str(exc.value)
    assert needle in msg and msg.startswith("x.yaml: ") and "\n" not in msg


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensors: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(bad)
    lst = tmp_path / "list.yaml"
    lst.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="must be a mapping"):
        load_config(lst)


def test_cli_reports_config_error_in_one_line(tmp_path):
    from click.testing import CliRunner

    from mavnav.cli import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("sensors:\n  gnss:\n    sigma_zz_m: 3\n")
    res = CliRunner().invoke(main, ["covariance", str(bad)])
    assert res.exit_code == 2
    assert "unknown key 'sensors.gnss.sigma_zz_m'" in res.output
    assert "Traceback" not in res.output


@pytest.mark.parametrize(
    "field, value",
    [
        ("dt_s", math.nan),
        ("dp_m", math.inf),
        ("dv_mps", -math.inf),
        ("baro_m", math.nan),
        ("dt_s", 0.0),
    ],
)
def test_wrong_epoch_input_is_refused_by_name(field, value):
    model = Model.from_config(Config())
    st = initial_state(model, 0, 0.0)
    ep = EpochInputs(t_us=20000, dt_s=0.02, dp_m=0.0, dv_mps=0.0, baro_m=0.0)
    bad = EpochInputs(**{**{f: getattr(ep, f) for f in ep.__slots__}, field: value})
    with pytest.raises(NonFiniteInputError, match=field):
        step("gnss", st, bad, model)


def test_wrong_aux_input_is_refused_by_name():
    model = Model.from_config(Config())
    st = initial_state(model, 0, 0.0)
    ep = EpochInputs(t_us=20000, dt_s=0.02, dp_m=0.0, dv_mps=0.0, baro_m=0.0,
                     gnss=AuxMeasurement(height_m=math.nan, sigma_m=1.0, age_s=0.0))
    with pytest.raises(NonFiniteInputError, match="gnss.height_m"):
        step("gnss", st, ep, model)
    # the rangefinder channel ignores GNSS, so the same epoch is still refused (all inputs are checked)
    with pytest.raises(NonFiniteInputError, match="gnss.height_m"):
        step("rangefinder", st, ep, model)
    assert np.all(np.isfinite(st.x))
