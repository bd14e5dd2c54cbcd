"""Shared fixtures and the test kinds.

Every test has a kind, a marker (a live replay of a shared log has two):

* ``unit``: closed-form and small deterministic checks of one module (the
  default: a test that declares no other kind is a unit test);
* ``property``: hypothesis-driven (covariance stays symmetric positive
  definite, same input same output, fuzzed bytes never crash); given to
  every hypothesis test automatically;
* ``simulation``: seeded simulation against exact truth (NEES, NIS, time to
  alarm, Monte Carlo);
* ``integration``: real sockets, processes, a browser, MAVProxy, a Dask
  cluster, the CLI as a subprocess;
* ``realdata``: the shared real logs in ``../shared`` (read in place;
  skipped, saying so, where they are not beside the checkout);
* ``golden``: behaviour unchanged, byte for byte: ``mavnav audit`` of the
  repository's own ``sitl_logs/`` against the JSON, CSV and table stored in
  ``tests/golden/`` (a few seconds, in the fast lane; ``make golden``
  rewrites them when a change of behaviour is meant, see
  ``tests/support/golden.py``).

A module declares its kind with ``pytestmark``; a test of another kind in it
says so with its own marker (``pytest --co -q -m realdata`` lists a kind). The kinds are orthogonal to ``slow`` (what the
fast lane, ``make test-fast`` = ``pytest -m "not slow"``, leaves out: Monte
Carlo runs, subprocesses and live links, long real logs, the browser).
Select a kind with ``-m``, e.g. ``pytest -m realdata`` or
``pytest -m "unit and not slow"``.

Markers rather than subdirectories: several modules mix kinds (a decoder's
unit tests beside its comparison with pyulog on the shared logs), and a test
can be slow whatever its kind.
"""

from __future__ import annotations

import pytest

from tests.support.emit import Peer
from tests.support.paths import SCENARIOS, SHARED

KINDS = ("unit", "property", "simulation", "integration", "realdata", "golden")


def pytest_collection_modifyitems(config, items):
    for item in items:
        fn = getattr(item, "obj", None)
        if getattr(fn, "is_hypothesis_test", False) and item.get_closest_marker("property") is None:
            item.add_marker(pytest.mark.property)
        kinds = [k for k in KINDS if item.get_closest_marker(k) is not None]
        if not kinds:
            item.add_marker(pytest.mark.unit)
        if "realdata" in kinds and not SHARED.is_dir():
            item.add_marker(pytest.mark.skip(reason=f"the shared real logs are not beside the checkout ({SHARED})"))


@pytest.fixture
def peer():
    """A pymavlink peer on a UDP port of 127.0.0.1 that decodes all it receives."""
    p = Peer()
    yield p
    p.close()


@pytest.fixture(scope="session")
def simulated_tlog(tmp_path_factory):
    """A factory: ``simulated_tlog(name, seed)`` is ``(path, result)``, the tlog
    mavnav's simulator writes for ``config/scenarios/<name>.yaml`` with that
    seed and its :class:`~mavnav.sim.SimResult`; each (name, seed) is
    simulated once per session, whichever modules ask for it."""
    from mavnav.sim import load_scenario, simulate

    made: dict = {}

    def make(name: str, seed: int):
        if (name, seed) not in made:
            res = simulate(load_scenario(SCENARIOS / f"{name}.yaml"), seed)
            path = tmp_path_factory.mktemp("sim") / f"{name}_{seed}.tlog"
            path.write_bytes(res.tlog)
            made[(name, seed)] = (path, res)
        return made[(name, seed)]

    return make
