"""``ipcsim compare A B``: regression comparison of two output folders.

Exit status 0 same within tolerance, 1 different, 2 cannot compare."""

from __future__ import annotations

from pathlib import Path


def main(args) -> int:
    from ..io.compare import compare_runs, format_summary, plot_result

    res = compare_runs(Path(args.a), Path(args.b), rtol=args.rtol, atol=args.atol)
    print(format_summary(res), flush=True)
    if args.plot:
        print(f"plot: {plot_result(res, args.plot)}")
    return 0 if res.same else 1
