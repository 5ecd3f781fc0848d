"""Write, or check, ipcsim/compiler/signatures.txt: the kernels compiled ahead of time when
ipcsim is installed, with the argument types of every call the scenes make from Python.

    python tools/kernel_signatures.py [SCENE[@STEPS] ...]
        runs each scene (STEPS steps; all by default) on one thread with numba alone,
        checks its frames, and rewrites the table with every kernel call that was made
    python tools/kernel_signatures.py --check [SCENE[@STEPS] ...]
        runs them as ipcsim runs (compiled kernels where there are) and lists each call
        the table lacks; exit 1 if there is one
    python tools/kernel_signatures.py --add [SCENE[@STEPS] ...]
        as --check, then adds those calls to the table and keeps every line it had (a
        rewrite keeps only the calls of the scenes it ran: other paths' calls go)

Without scenes, the list below: the project's scenes and the original's tutorial and
paper examples from ../shared/ipc-examples (each to some contact, with friction where it
has any). A call that passes an array numba types otherwise than the table can hold
(read-only, strided) is reported and left out: it should not be made.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT.parent / "shared" / "ipc-examples" / "input"

SCENES = [
    "input/two_cubes_fall.txt", "input/cube_drop.toml", "input/two_cubes_fall_frictionless.txt",
    # 2D: the lecture's lessons (lines, springs, triangles, point-edge contact, friction)
    "input/tutorial/2_dirichlet.toml@5", "input/tutorial/4_friction.toml@20",
    "input/tutorial/5_mov_dirichlet.toml@40", "input/tutorial/7_self_contact.toml@40",
    "input/tutorial/8_self_friction.toml@40",
    *(str(p) for p in sorted(EXAMPLES.glob("tutorialExamples/**/*.txt"))),
    f"{EXAMPLES}/paperExamples/10_cubeStack.txt",
    f"{EXAMPLES}/otherExamples/friction/slopeTest_highSchoolPhysics_0.49.txt@30",
    f"{EXAMPLES}/paperExamples/2_matKnives.txt@15",
    f"{EXAMPLES}/paperExamples/21_scalability/mat40x40_twist.txt@3",
    f"{EXAMPLES}/paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.1.txt@8",
    # its large steps pull prescribed vertices (boundary_pull.py)
    f"{EXAMPLES}/paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.2.txt",
    f"{EXAMPLES}/paperExamples/20_pencilStickSlip.txt@20",
    f"{EXAMPLES}/otherExamples/barTwist_noCollisions.txt@3",
]

HEADER = """\
# The kernels ipcsim compiles ahead of time when it is installed, with the argument types
# of each compiled variant (ipcsim/compiler/aot.py). A call whose types are not listed here
# is compiled by numba on first use. Written by tools/kernel_signatures.py from the calls
# its scenes make.
"""


def record(scenes: list[str]) -> list[str]:
    """Run each ``SCENE[@STEPS]`` on one thread, check its frames, and return every kernel
    call that went to numba as a table line."""
    os.environ["IPCSIM_THREADS"] = "1"
    from ipcsim.compiler import aot

    aot.start_recording()
    import ipcsim
    from ipcsim.contact.frame_check import check_frames

    with tempfile.TemporaryDirectory() as out, open(os.devnull, "w") as quiet:
        for i, scene in enumerate(scenes):
            path, _, steps = scene.partition("@")
            folder = Path(out) / str(i)
            print(f"running {scene}", file=sys.stderr)
            ipcsim.run(ipcsim.load_scene(path), folder, steps=int(steps) if steps else None,
                       mode="overwrite")
            check_frames(folder, out=quiet)
    return aot.recorded_calls()


def merged(table: list[str], calls: list[str]) -> str:
    """The table's text with ``calls`` added: every line once, in order."""
    return HEADER + "\n".join(sorted(set(table) | set(calls))) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python tools/kernel_signatures.py",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", help="SCENE[@STEPS] (default: the list)")
    parser.add_argument("--check", action="store_true",
                        help="list the calls the table lacks instead of rewriting it")
    parser.add_argument("--add", action="store_true",
                        help="add the calls the table lacks, keeping its other lines")
    args = parser.parse_args(argv)
    if not (args.check or args.add):
        os.environ["IPCSIM_AOT"] = "0"  # every call goes to numba and is recorded
    os.chdir(ROOT)
    sys.path.insert(0, str(ROOT))
    from ipcsim.compiler import aot

    lines = record(args.scenes or SCENES)
    odd = [line for line in lines if "?" in line]
    for line in odd:
        print(f"an argument no compiled kernel can take (read-only or strided?): {line}",
              file=sys.stderr)
    lines = [line for line in lines if "?" not in line]
    if args.check or args.add:
        table = [f"{m}.{f}({', '.join(aot.format_key(k) for k in key)})"
                 for m, f, key in aot.read_table()]
        missing = [line for line in lines if line not in set(table)]
        for line in missing:
            print(f"not in {aot.TABLE.name}: {line}")
        if args.add:
            aot.TABLE.write_text(merged(table, missing), encoding="utf-8")
            print(f"{len(missing)} signatures added -> {aot.TABLE}")
            return 1 if odd else 0
        return 1 if missing or odd else 0
    aot.TABLE.write_text(HEADER + "\n".join(lines) + "\n", encoding="utf-8")
    print(f"{len(lines)} signatures -> {aot.TABLE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
