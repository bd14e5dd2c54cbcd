"""``mavnav covariance CONFIG.yaml``: RMS of each state over time, per channel, no data."""

from __future__ import annotations

import json

import click

from . import main

_REPORT_TIMES_S = (0.0, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0)


@main.command("covariance")
@click.argument("config_path", metavar="CONFIG.yaml", type=click.Path(dir_okay=False))
@click.option("--duration", "duration_s", type=click.FloatRange(min=0.0, min_open=True), default=5.0,
              show_default=True, help="Seconds of the recursion.")
@click.option("--json", "as_json", is_flag=True, help="Print the full series as JSON.")
def covariance_cmd(config_path: str, duration_s: float, as_json: bool) -> None:
    """Run the covariance recursion of each channel (no data) and report the RMS
    of height, vertical speed, baro bias and accelerometer bias over time."""
    import numpy as np

    from ..config import load_config
    from ..covariance import covariance_analysis

    cfg = load_config(config_path)
    result = covariance_analysis(cfg, duration_s)
    if as_json:
        click.echo(json.dumps({"channels": {k: s.as_json() for k, s in result.items()}}))
        return
    f = cfg.filter
    click.echo(f"covariance analysis: T = {f.step_s} s, {duration_s:g} s, accel noise form '{f.accel_noise_form}'")
    for kind, s in result.items():
        click.echo(f"\nchannel {kind}")
        click.echo(f"{'t_s':>8} {'height_m':>10} {'vel_mps':>10} {'baro_bias_m':>12} {'acc_bias_mps2':>14}")
        times = [t for t in _REPORT_TIMES_S if t <= duration_s + 1e-9] + [float(s.t_s[-1])]
        seen = set()
        for t in times:
            i = int(np.argmin(np.abs(s.t_s - t)))
            if i in seen:
                continue
            seen.add(i)
            click.echo(f"{s.t_s[i]:8.2f} {s.rms_height_m[i]:10.4f} {s.rms_vel_mps[i]:10.4f} "
                       f"{s.rms_baro_bias_m[i]:12.4f} {s.rms_acc_bias_mps2[i]:14.5f}")
