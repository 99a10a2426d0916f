"""``python -m dcmviz.run``: see :mod:`dcmviz.run.runner`."""

import sys

from dcmviz.run.runner import main

sys.exit(main())
