"""``ipcsim compare A B``: regression comparison of two output folders.

Exit status 0 same within tolerance, 1 different, 2 cannot compare."""

from __future__ import annotations

from pathlib import Path


def main(args) -> int:
    from ..io.compare import compare_runs, format_summary, plot_result

    res = compare_runs(Path(args.a), Path(args.b), rtol=args.rtol, atol=args.atol)
    plot = plot_result(res, args.plot) if args.plot else None  # an unwritable plot: 2
    print(format_summary(res), flush=True)
    if plot is not None:
        print(f"plot: {plot}")
    return 0 if res.same else 1
