"""Scenario simulator and fault injector: MAVLink telemetry with known truth.

In-process use (a scorecard)::

    from mavnav.sim import load_scenario, simulate
    scn = load_scenario("config/scenarios/px4_landing_nominal.yaml")
    res = simulate(scn, seed=7)          # SimResult
    res.tlog                              # bytes of a .tlog (8-byte BE receive time + frame)
    res.truth["true_height_ref_m"]        # truth at scenario.truth_rate_hz, vehicle clock in "t_s"
    res.trajectory.sample(t_sim)          # truth at any simulation time
    res.faults                            # fault windows (scenario time and vehicle time)

    from mavnav.sim import inject_bytes, parse_fault
    out, report = inject_bytes(data, [parse_fault("gnss_step:onset=60,duration=20,magnitude=10")])

Conventions: see :mod:`mavnav` (heights up, units in names, vehicle time vs
receive time). Sensor models: MODEL.md (``../shared/docs/``) sections 2-4 with its errata.
"""

from .faults import FAULT_SYNTAX_HELP, parse_fault, sidecar_path
from .inject import inject_bytes, inject_file
from .scenario import FAULT_MAGNITUDE, FAULT_SOURCE, Fault, Scenario, load_scenario, scenario_from_dict
from .simulate import SimResult, Truth, read_truth_csv, simulate

__all__ = [
    "FAULT_MAGNITUDE",
    "FAULT_SOURCE",
    "FAULT_SYNTAX_HELP",
    "Fault",
    "Scenario",
    "SimResult",
    "Truth",
    "inject_bytes",
    "inject_file",
    "load_scenario",
    "parse_fault",
    "read_truth_csv",
    "scenario_from_dict",
    "sidecar_path",
    "simulate",
]
