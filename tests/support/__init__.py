"""What the tests share: simulated data, MAVLink peers and writers, readers of
what mavnav writes, and where the data lives (:mod:`tests.support.paths`).

Imported as ``tests.support.<module>`` (``tests`` is a package; pytest puts
the repository root on ``sys.path``). Fixtures built on these are in
``tests/conftest.py``.
"""
