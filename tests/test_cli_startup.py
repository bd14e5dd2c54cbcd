"""The CLI starts without the estimator's heavy dependencies (issue 15).

``mavnav --help`` should answer at once: scipy.stats (0.8 s), rerun (0.5 s)
and numba (0.3 s) are imported by the commands that use them, when they run.
Each check runs in a fresh interpreter and reads its ``sys.modules``: it
fails on the import itself, not on a timing (``bench/startup.py`` times it).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration  # the CLI in subprocesses

REPO = Path(__file__).resolve().parents[1]

# What the brief names, and what else a parse does not need: the monitor's
# dependencies, the MAVLink library and the configuration models.
HEAVY = ("scipy", "scipy.stats", "rerun", "numba", "numpy", "pymavlink", "pydantic", "mavnav.monitor",
         "mavnav.ingest", "mavnav.config")


def _modules_after(code: str) -> set[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)), file=sys.__stderr__)\n"
    r = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60, cwd=REPO)
    return set(json.loads(r.stderr.strip().splitlines()[-1]))


def test_import_cli_pulls_in_no_scipy_stats_rerun_or_numba():
    mods = _modules_after("import mavnav.cli")
    assert "mavnav.cli.audit" in mods  # the commands are registered
    for name in ("scipy.stats", "rerun", "numba"):
        assert name not in mods, f"import mavnav.cli imports {name}"


@pytest.mark.parametrize("argv", [["--help"]] + [pytest.param(a, marks=pytest.mark.slow) for a in
                                                 (["audit", "--help"], ["run", "--help"], ["replay", "--help"])])
def test_help_imports_nothing_heavy(argv):
    code = ("import sys\nfrom mavnav.cli import main\n"
            f"try:\n    main({argv!r}, prog_name='mavnav')\nexcept SystemExit:\n    pass\n")
    mods = _modules_after(code)
    assert not [m for m in HEAVY if m in mods], f"mavnav {' '.join(argv)} imports {[m for m in HEAVY if m in mods]}"


@pytest.mark.slow
def test_a_command_still_gets_what_it_needs(tmp_path):
    """The deferred imports happen when the command runs: covariance prints its table."""
    code = ("from mavnav.cli import main\n"
            f"try:\n    main(['covariance', {str(REPO / 'config/paper_2015_covariance.yaml')!r}, "
            "'--duration', '0.2'], prog_name='mavnav')\nexcept SystemExit as e:\n    assert not e.code, e.code\n")
    mods = _modules_after(code)
    assert "numpy" in mods and "mavnav.config" in mods
