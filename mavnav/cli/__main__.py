"""``python -m mavnav.cli``: the same entry point as the ``mavnav`` command."""

from . import main

if __name__ == "__main__":
    main()
