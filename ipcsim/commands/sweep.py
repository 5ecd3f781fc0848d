"""``ipcsim sweep STUDY.toml``: run a study (docs/user-guide.md, "Studies") on a local
Dask cluster (``--workers N``), an existing one (``--scheduler ADDRESS``) or in this
process (``--serial``), and write study.csv and the chart.

Exit status: 0 every run finished, 1 the study finished but some runs failed (their rows
say why), 2 bad input (the study file, a scene key or value) or Dask missing, 130
interrupted (re-running the study continues it)."""

from __future__ import annotations

import sys
from pathlib import Path


def main(args) -> int:
    from ..study import default_output, load_study, run_study
    from ..study.executors import DaskExecutor, SerialExecutor
    from ..io.progress import RunProgress

    study = load_study(args.study)
    if args.serial:
        executor = SerialExecutor()
    else:
        executor = DaskExecutor(args.workers, args.scheduler)
    out = Path(args.output) if args.output else default_output(study)
    say = (lambda m: None) if args.quiet else (lambda m: print(m, flush=True))
    result = run_study(study, out, executor, RunProgress.mode_for(args.quiet), say,
                       overwrite=args.overwrite)
    say(f"wrote {result.table}" + (f" and {result.chart}" if result.chart else "")
        + f": {len(result.rows)} runs ({result.ran} run now), {result.failed} failed")
    if result.chart is None:
        print(f"warning: no chart: no finished run has a number in study.csv's column "
              f"'{study.chart.y}' (chart.y)", file=sys.stderr, flush=True)
    return 1 if result.failed else 0
