"""``python -m ipcsim``: the same command line as ``ipcsim``."""

from .cli import console

console()
