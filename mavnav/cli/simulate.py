"""``mavnav simulate SCENARIO.yaml -o OUT.tlog``: MAVLink telemetry with known truth."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import click

from . import main
from .honest import check_outputs


@main.command("simulate")
@click.argument("scenario_path", metavar="SCENARIO.yaml", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out_path", required=True, type=click.Path(dir_okay=False),
              help="The .tlog to write (8-byte big-endian receive time in us, then one MAVLink frame).")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the truth CSV (t_s = vehicle clock, heights, speed, fault state).")
@click.option("--seed", type=int, default=None, help="Random seed (default: the scenario's).")
def simulate_cmd(scenario_path: str, out_path: str, truth_path: Optional[str], seed: Optional[int]) -> None:
    """Simulate SCENARIO.yaml: the sensor models of docs/MODEL.md on a truth
    trajectory, with the scenario's faults, encoded as a real autopilot's
    MAVLink stream. Writes OUT.tlog, OUT.faults.json (fault windows) and, with
    --truth, a truth CSV at the scenario's truth_rate_hz. Same seed, same bytes."""
    from ..sim import load_scenario, sidecar_path, simulate

    scn = load_scenario(scenario_path)
    out = Path(out_path)
    check_outputs({"-o": out, "the fault sidecar": sidecar_path(out), "--truth": truth_path})
    res = simulate(scn, seed)
    res.write(out, truth_path)
    t = res.timings_s
    click.echo(
        f"{out}: {int(t['records'])} records, {len(res.tlog)} bytes, {scn.duration_s:g} s "
        f"({scn.profile}, seed {res.seed}) in {t['total']:.2f} s; faults -> {sidecar_path(out)}"
        + (f"; truth -> {truth_path}" if truth_path else "")
    )
