"""Run ``ipcsim`` and SIGKILL itself at a chosen point of its writing (a test helper, run
as a script by tests/test_fault_injection.py):

    python kill_points.py POINT N ipcsim-arguments...

POINT names where the N-th such event of the process kills it:

* ``before-rename``: a file is completely written under its temporary name, not renamed;
* ``mid-write``: half of a file is written under its temporary name;
* ``after-rename``: a file has just replaced its target (the next one is not begun);
* ``mid-row``: half of a CSV row is written and flushed;
* ``after-row``: a CSV row is written and flushed.

Every ipcsim file is renamed into place with ``os.replace`` (frames, ``series.pvd``,
``checkpoint.npz``, ``scene.toml``, ``run.json``, rewritten logs), and every CSV row goes
through ``CsvLog._write_line``; the helper wraps those two and nothing else.
"""

from __future__ import annotations

import os
import signal
import sys


def _die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def install(point: str, n: int) -> None:
    from ipcsim.io import csv_log

    seen = [0]

    def due() -> bool:
        seen[0] += 1
        return seen[0] == n

    real_replace = os.replace
    real_write_line = csv_log.CsvLog._write_line

    def replace(src, dst, *args, **kwargs):
        if point in ("before-rename", "mid-write") and due():
            if point == "mid-write":
                size = os.path.getsize(src)
                with open(src, "r+b") as f:
                    f.truncate(size // 2)
            _die()
        real_replace(src, dst, *args, **kwargs)
        if point == "after-rename" and due():
            _die()

    def write_line(self, line):
        if point == "mid-row" and due():
            self._file.write(line[: len(line) // 2])
            self._file.flush()
            _die()
        real_write_line(self, line)
        if point == "after-row" and due():
            _die()

    os.replace = replace
    csv_log.CsvLog._write_line = write_line


if __name__ == "__main__":
    install(sys.argv[1], int(sys.argv[2]))
    from ipcsim.cli import main

    sys.exit(main(sys.argv[3:]))
