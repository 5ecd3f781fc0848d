"""Regenerate the golden references in tests/regression/golden/ after an intended change.

    python tests/regression/regenerate.py                 # every scene
    python tests/regression/regenerate.py cube_drop ...   # only these
    python tests/regression/regenerate.py --into DIR ...  # write to DIR, keep golden/

Each scene runs for its steps into a temporary folder; the run is compared with the old
reference by the same comparison as ``ipcsim compare`` and the verdict printed, then the
reference is rewritten. Scenes of the original's examples are skipped when absent.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
# this checkout's ipcsim, tests/examples.py and golden_scenes.py, from any working folder
sys.path[:0] = [str(HERE.parents[1]), str(HERE.parent), str(HERE)]

from golden_scenes import RTOL, SCENES  # noqa: E402

from ipcsim.io.compare import (COUNT_COLUMNS, CompareError, compare_runs,  # noqa: E402
                               format_summary, golden_from_run, write_golden)
from ipcsim.io.csv_log import read_csv  # noqa: E402


def newton_margin(out: Path) -> tuple[float, int]:
    """How close any Newton iteration came to the convergence test ‖p‖∞ < tol, as the
    factor max(r, 1/r) of r = ‖p‖∞ / tol, and its step. Near 1, round-off on another
    machine could add or save an iteration, and the exact count check would flag it."""
    log = read_csv(out / "newton.csv")
    r = log["residual_ratio"]
    factor = [max(x, 1 / x) if x > 0 else float("inf") for x in r]
    k = min(range(len(factor)), key=factor.__getitem__)
    return float(factor[k]), int(log["step"][k])


def _changed_counts(res) -> list[str]:
    """Per column, the steps whose count differs from the old reference."""
    lines = []
    for c in COUNT_COLUMNS:
        a, b = res.counts_a.get(c), res.counts_b.get(c)
        if a is None:
            continue
        steps = [s for s, x, y in zip(res.log_steps, a, b) if x != y]
        if steps:
            lines.append(f"  {c} differs at {len(steps)} steps: "
                         + " ".join(str(s) for s in steps[:12]) + (" ..." * (len(steps) > 12)))
    return lines


def regenerate(scene, into: Path) -> bool:
    path = scene.path()
    if path is None:
        print(f"{scene.name}: skipped, the original's examples are not present")
        return True
    target = into / scene.golden.name
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        if scene.run(out) != 0:
            print(f"{scene.name}: the run failed, reference left as it was")
            return False
        margin, step = newton_margin(out)
        golden = golden_from_run(out, about={
            "scene": scene.scene, "original_example": scene.original_example,
            "steps": scene.steps, "covers": scene.covers,
            "closest_newton_ratio": margin, "closest_newton_step": step})
        print(f"{scene.name}: {scene.steps} steps; closest Newton iteration to the "
              f"threshold: factor {margin:.3g} (step {step})")
        if target.is_file():
            try:
                res = compare_runs(out, target, rtol=RTOL)
                print("  against the old reference (A: this run, B: the old reference)")
                print("  " + format_summary(res).replace("\n", "\n  "))
                print("\n".join(_changed_counts(res)) or "  counts unchanged")
            except CompareError as exc:
                print(f"  cannot compare with the old reference: {exc}")
        else:
            print("  new reference")
        write_golden(target, golden)
    print(f"  wrote {target} ({target.stat().st_size} bytes)")
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", metavar="SCENE",
                        help="scene names (default: all): " + ", ".join(s.name for s in SCENES))
    parser.add_argument("--into", type=Path, default=SCENES[0].golden.parent, metavar="DIR",
                        help="folder to write the references to (default: golden/)")
    args = parser.parse_args(argv)
    known = {s.name: s for s in SCENES}
    unknown = [n for n in args.scenes if n not in known]
    if unknown:
        parser.error(f"unknown scene(s) {', '.join(unknown)}; known: {', '.join(known)}")
    args.into.mkdir(parents=True, exist_ok=True)
    chosen = [known[n] for n in args.scenes] or SCENES
    return 0 if all([regenerate(s, args.into) for s in chosen]) else 1


if __name__ == "__main__":
    sys.exit(main())
