"""``python -m dcmviz.sweep``: the sweep's command line (see :mod:`dcmviz.sweep`)."""

import sys

from dcmviz.sweep import main

sys.exit(main())
