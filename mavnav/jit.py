"""``njit`` from numba (a dependency), or a no-op decorator without it, so the
compiled kernels also run (slowly) as plain Python."""

try:
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ["njit"]
