"""``python -m ipcsim``: the same command line as ``ipcsim``."""

import sys

from .cli import main

sys.exit(main())
