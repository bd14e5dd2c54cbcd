"""Scenario files: examples load, bad files are refused by name, the CLI writes its outputs."""

from __future__ import annotations

import json

import pytest
import yaml
from click.testing import CliRunner
from pydantic import BaseModel, Field, ValidationError
from pymavlink import mavutil

from mavnav.cli import main
from mavnav.config import (
    BaroNoise, FilterConfig, GnssNoise, InsNoise, RangefinderNoise, SensorsConfig, truth_field,
)
from mavnav.errors import ConfigError
from mavnav.sim import load_scenario, read_truth_csv, scenario_from_dict
from mavnav.sim.scenario import Scenario
from tests.support.paths import REPO

ROOT = REPO
SCENARIOS = sorted((ROOT / "config" / "scenarios").glob("*.yaml"))
MIN = {"duration_s": 10, "trajectory": {"kind": "hover"}}


def test_examples_exist_and_load():
    assert len(SCENARIOS) >= 5
    for p in SCENARIOS:
        scn = load_scenario(p)
        assert scn.name == p.stem


# The filter's model of each sensor and the simulator's truth of it share their noise keys
# (mavnav.config's *Noise sections): one key, unit and bound each, each side its own values.
NOISE = {"ins": InsNoise, "baro": BaroNoise, "gnss": GnssNoise, "rangefinder": RangefinderNoise}


@pytest.mark.parametrize("section", sorted(NOISE))
def test_the_truth_and_the_model_share_their_noise_keys(section):
    noise = NOISE[section]
    model = SensorsConfig.model_fields[section].annotation
    truth = Scenario.model_fields["sensors"].annotation.model_fields[section].annotation
    assert issubclass(model, noise) and issubclass(truth, noise)
    for key in noise.model_fields:
        for value, model_ok, truth_ok in ((0.5, True, True), (-1.0, False, False),
                                          (0.0, False, key.startswith("sigma"))):  # a simulated sensor may be noise-free
            for cls, ok in ((model, model_ok), (truth, truth_ok)):
                try:
                    cls(**{key: value})
                    assert ok, f"{cls.__name__}.{key} = {value} accepted"
                except ValidationError:
                    assert not ok, f"{cls.__name__}.{key} = {value} refused"


def test_the_truth_keeps_its_own_values_and_only_its_keys():
    truth, model = scenario_from_dict(MIN).sensors, SensorsConfig()
    # the defaults differ: a simulator whose sensors equal the model by construction proves nothing
    assert (truth.ins.sigma_a_mps2, truth.baro.sigma_bb_m, truth.gnss.sigma_z_m) != \
        (model.ins.sigma_a_mps2, model.baro.sigma_bb_m, model.gnss.sigma_z_m)
    assert truth.ins.gravity_mps2 == FilterConfig().gravity_mps2
    # what only the model has is no key of the truth (nothing simulated would read it)
    with pytest.raises(ConfigError, match="unknown key 'sensors.ins.bias_rw_mps2_per_sqrt_s'"):
        scenario_from_dict(dict(MIN, sensors={"ins": {"bias_rw_mps2_per_sqrt_s": 0.0}}))
    with pytest.raises(ConfigError, match="unknown key 'sensors.gnss.gm_sigma_m'"):
        scenario_from_dict(dict(MIN, sensors={"gnss": {"gm_sigma_m": 1.0}}))


def test_truth_field_carries_bounds_only():
    class Odd(BaseModel):
        x: float = Field(1.0, multiple_of=0.5)

    with pytest.raises(TypeError, match="Odd.x"):
        truth_field(Odd, "x")


def _write(tmp_path, data, name="s.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return p


@pytest.mark.parametrize(
    "data,needle",
    [
        (dict(MIN, durration_s=3), "unknown key 'durration_s'"),
        (dict(MIN, sensors={"baro": {"sigma_bb": 1}}), "unknown key 'sensors.baro.sigma_bb'"),
        (dict(MIN, trajectory={"kind": "hover", "hieght_m": 3}), "unknown key 'trajectory.hieght_m'"),
        (dict(MIN, trajectory={"kind": "spiral"}), "trajectory"),
        (dict(MIN, rates_hz={"HIGHRES_IMUU": 100}), "unknown key 'rates_hz.HIGHRES_IMUU'"),
        (dict(MIN, rates_hz={"ATTITUDE": -1}), "rates_hz.ATTITUDE"),
        (dict(MIN, faults=[{"kind": "gnss_jump", "onset_s": 1, "magnitude": 1}]), "faults[0].kind"),
        (dict(MIN, faults=[{"kind": "gnss_step", "onset_s": 1}]), "gnss_step needs a magnitude"),
        (dict(MIN, faults=[{"kind": "gnss_step", "onset_s": 1, "magnitude": 1, "probablity": 0.2}]),
         "unknown key 'faults[0].probablity'"),
        (dict(MIN, faults=[{"kind": "rng_dropout", "onset_s": 1, "mode": "nofix"}]), "rng_dropout mode must be one of"),
        (dict(MIN, faults=[{"kind": "link_loss", "onset_s": 1}]), "link_loss needs a duration_s"),
        (dict(MIN, faults=[{"kind": "rate_drop", "onset_s": 1, "magnitude": 2}]), "0 < m < 1"),
        (dict(MIN, faults=[{"kind": "gnss_step", "onset_s": 1, "magnitude": 1, "messages": ["GPS_RAW_INT"]}]),
         "only rate_drop takes messages"),
        (dict(MIN, sensors={"rangefinder": {"min_m": 5, "max_m": 2}}), "max_m must exceed min_m"),
        (dict(MIN, rates_hz={"HIGHRES_IMU": 0}), "no IMU message"),
        (dict(MIN, faults=[{"kind": "baro_freeze", "onset_s": 10}]), "faults[0].onset_s is after the scenario ends"),
        ({"trajectory": {"kind": "hover"}}, "missing key 'duration_s'"),
        ("duration_s: [1, 2\n", "not valid YAML at line"),
        ("- 1\n- 2\n", "top level must be a mapping"),
    ],
)
def test_bad_scenarios_are_refused_by_name(tmp_path, data, needle):
    p = _write(tmp_path, data)
    with pytest.raises(ConfigError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert needle in msg
    assert "\n" not in msg and msg.startswith(str(p))


def test_missing_scenario_file(tmp_path):
    with pytest.raises(ConfigError, match="no such scenario file"):
        load_scenario(tmp_path / "nope.yaml")


def test_cli_simulate_writes_tlog_truth_and_sidecar(tmp_path):
    scn = _write(tmp_path, dict(MIN, faults=[{"kind": "gnss_step", "onset_s": 4, "duration_s": 2, "magnitude": 5}]))
    out, truth = tmp_path / "o.tlog", tmp_path / "o.csv"
    r = CliRunner().invoke(main, ["simulate", str(scn), "-o", str(out), "--truth", str(truth), "--seed", "3"])
    assert r.exit_code == 0, r.output
    conn = mavutil.mavlink_connection(str(out))
    types = set()
    while (m := conn.recv_msg()) is not None:
        types.add(m.get_type())
    conn.close()
    assert {"HIGHRES_IMU", "GPS_RAW_INT", "SCALED_PRESSURE", "DISTANCE_SENSOR", "HEARTBEAT"} <= types
    t = read_truth_csv(truth)
    assert list(t)[:5] == ["t_s", "boot", "t_sim_s", "true_height_ref_m", "true_alt_msl_m"]
    side = json.loads((tmp_path / "o.faults.json").read_text())
    assert side["seed"] == 3 and side["faults"][0]["kind"] == "gnss_step"
    assert side["faults"][0]["onset_s"] == 4 and side["faults"][0]["end_s"] == 6
    # the same command again gives the same bytes
    first = out.read_bytes()
    CliRunner().invoke(main, ["simulate", str(scn), "-o", str(out), "--seed", "3"])
    assert out.read_bytes() == first


def test_cli_simulate_bad_file_is_one_line(tmp_path):
    scn = _write(tmp_path, dict(MIN, colour="red"))
    r = CliRunner().invoke(main, ["simulate", str(scn), "-o", str(tmp_path / "o.tlog")])
    assert r.exit_code == 2
    assert "unknown key 'colour'" in r.output
    assert not (tmp_path / "o.tlog").exists()


SITL = ROOT / "sitl_logs"
SITL_NAMES = sorted(p.name[: -len(".tlog")] for p in SITL.glob("*.tlog"))


@pytest.mark.slow
def test_committed_sitl_logs_match_their_scenarios(tmp_path):
    """Golden files: the committed logs are exactly what their scenarios generate."""
    from mavnav.sim import simulate

    assert len(SITL_NAMES) >= 5
    for name in SITL_NAMES:
        res = simulate(load_scenario(ROOT / "config" / "scenarios" / f"{name}.yaml"))
        assert res.tlog == (SITL / f"{name}.tlog").read_bytes(), f"{name}: run sitl_logs/regenerate.sh"
        # the truth CSV byte for byte: a column added since makes a stale file
        res.truth.to_csv(tmp_path / f"{name}.truth.csv")
        assert (tmp_path / f"{name}.truth.csv").read_bytes() == (SITL / f"{name}.truth.csv").read_bytes(), \
            f"{name}: run sitl_logs/regenerate.sh"


def test_filter_sensors_carry_the_scenario_noise():
    scn = scenario_from_dict(dict(MIN, sensors={"ins": {"sigma_a_mps2": 0.07, "alpha_a_per_s": 3.0},
                                                "baro": {"sigma_bb_m": 0.4, "gamma_bb_per_s": 2.0},
                                                "gnss": {"sigma_z_m": 0.6, "correlated_sigma_m": 0.8},
                                                "rangefinder": {"sigma_m": 0.03}}))
    f = scn.filter_sensors()
    assert isinstance(f, SensorsConfig)
    assert (f.ins.sigma_a_mps2, f.ins.alpha_a_per_s) == (0.07, 3.0)
    assert (f.baro.sigma_bb_m, f.baro.gamma_bb_per_s) == (0.4, 2.0)
    assert f.gnss.sigma_z_m == pytest.approx(1.0)
    assert f.rangefinder.sigma_m == 0.03
