"""``python -m hybridnav``: the ``hybridnav`` command."""

import sys

from hybridnav.cli import main

__all__: list[str] = []

if __name__ == "__main__":
    sys.exit(main())
