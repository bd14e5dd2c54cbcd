"""The benchmark scripts (run as ``python bench/<script>.py``); a package too, so
that the tests import the modules they check as ``bench.<module>``."""
