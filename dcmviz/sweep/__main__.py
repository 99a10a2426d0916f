"""``python -m dcmviz.sweep``: the sweep's command line (see :mod:`dcmviz.sweep`)."""

import sys

from dcmviz.sweep.cli import main

if __name__ == "__main__":
    sys.exit(main())
