"""The ``ipcsim`` command line: ``main(argv) -> exit status``.

Exit status: 0 success, 1 a check or comparison found a difference, 2 bad input (scene,
mesh, arguments, a damaged run folder) or an output folder that cannot be used or written,
3 the simulation failed, 130 interrupted. Library code raises typed errors (``ipcsim.errors``); only this module
turns them into messages, so a user never sees a Python traceback for a mistake of theirs.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import warnings
from typing import NoReturn

# OpenBLAS (numpy's, and kvxopt's under CHOLMOD) on one thread unless the user says
# otherwise, set before numpy loads it: its idle worker spins, about 0.1 s of another
# core at every start and, beside numba's threads, their time; CHOLMOD's factorisations
# measured no slower on one BLAS thread (2026-12-03; the figures are in git history).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from . import __version__  # noqa: E402  (numpy loads later, after the BLAS setting)
from .errors import IpcsimError, SceneError, one_line  # noqa: E402
from .start_up import end_process, pause_collector, resume_collector  # noqa: E402


def _command_main(name: str):
    """``main`` of ``commands/<name>.py``, imported only when chosen (each pulls in what
    only it needs)."""
    import importlib

    return importlib.import_module(f".commands.{name}", __package__).main


def _positive_int(text: str) -> int:
    """argparse type: a whole number >= 1 (``ipcsim.arguments``, as the API checks it)."""
    from .arguments import whole_number_at_least_1
    from .errors import ArgumentError

    try:
        return whole_number_at_least_1(text)
    except ArgumentError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _finite_float(text: str) -> float:
    """argparse type: a finite number (``ipcsim.arguments``)."""
    from .arguments import finite_number
    from .errors import ArgumentError

    try:
        return finite_number(text)
    except ArgumentError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _Parser(argparse.ArgumentParser):
    """argparse with a usage error on one line (exit status 2), like every other error."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``ipcsim`` parser; given ``command``, only that command's options are added
    (every command is still listed): argparse makes a help formatter for each option
    it adds, and a run paid a millisecond for the options of the other five."""
    parser = _Parser(
        prog="ipcsim",
        description="Incremental Potential Contact simulator driven by scene files "
        "(the original IPC text format or TOML).",
        epilog="Exit status: 0 success, 1 check --frames or compare found a difference "
        "(sweep: some runs failed), "
        "2 bad input or an output folder that cannot be used, 3 the simulation failed, "
        "130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"ipcsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, add in _COMMANDS.items():
        add(sub, options=command in (None, name))
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The command ``argv`` names (its first word that is not an option), if it is one:
    ``ipcsim`` itself has no option that takes a value."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in _COMMANDS else None


def _add_check(sub, options: bool = True) -> None:
    p = sub.add_parser("check", help="read a scene, build its model and print what it "
                       "contains (refusing what run refuses); or verify a run's frames "
                       "(--frames)")
    if not options:
        return
    p.add_argument("scene", nargs="?", help="scene file (.txt or .toml)")
    p.add_argument("--frames", metavar="OUT",
                   help="check every frame of the run in OUT for intersections (a body "
                        "inside another included), inverted tets and vertices below a "
                        "plane (exact predicates); exit 1 if any. The planes come from "
                        "OUT/scene.toml, or from SCENE (with --set) when given, which "
                        "must be the run's")
    _add_set(p)


def _add_set(p) -> None:
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene value by its dotted TOML key, the value read as "
                        "TOML (time.dt=0.01, contact.dhat=1e-3, shapes.0.material.E=1e6); "
                        "repeatable; the resolved scene.toml records it")


def _add_run(sub, options: bool = True) -> None:
    p = sub.add_parser("run", help="simulate a scene and write frames and logs",
                       description="Simulate a scene and write frames and logs. Shows a "
                       "progress bar on a terminal and a line every 5 % of the steps (or "
                       "30 s) otherwise. Ctrl-C or SIGTERM stops after the current step (exit status "
                       "130); --resume continues. Exit status: 0 done, 2 bad input or an "
                       "output folder that cannot be used or written, 3 the simulation "
                       "failed (NaN, solver), 130 interrupted.")
    if not options:
        return
    p.add_argument("scene", help="scene file (.txt or .toml)")
    _add_set(p)
    p.add_argument("-o", "--output", metavar="DIR",
                   help="output folder (default: output/<scene-stem>, with _<appendStr> "
                        "when the scene sets appendStr)")
    again = p.add_mutually_exclusive_group()
    again.add_argument("--overwrite", action="store_true",
                       help="replace an existing output folder (its old run is removed only "
                            "once the new one has been built and checked)")
    again.add_argument("--resume", action="store_true",
                       help="continue the run in the output folder from its last checkpoint "
                            "(written with a frame at most every 2 s, at the end and on Ctrl-C), "
                            "e.g. after a crash")
    p.add_argument("--steps", type=_positive_int, metavar="N",
                   help="stop after step N (default: ceil(duration/dt))")
    p.add_argument("--render", action="store_true",
                   help="also draw each frame as a PNG into DIR/render as it is written "
                        "(the camera frames the initial scene; `ipcsim render` frames the "
                        "whole run)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="print every Newton iteration as it happens")


def _add_sweep(sub, options: bool = True) -> None:
    p = sub.add_parser("sweep", help="run a study: many runs of a scene with values varied, "
                       "on a Dask cluster; writes study.csv and a chart",
                       description="Run a study file: its runs on a local Dask cluster of "
                       "single-threaded worker processes (one per core), an existing "
                       "cluster (--scheduler) or this process (--serial); one folder per "
                       "run, study.csv (a row per run) and study.png. Re-running skips "
                       "finished runs and resumes interrupted ones. Exit status: 0 all runs "
                       "finished, 1 some runs failed, 2 bad input or Dask missing, 130 "
                       "interrupted.")
    if not options:
        return
    p.add_argument("study", help="study file (.toml)")
    p.add_argument("-o", "--output", metavar="DIR",
                   help="study folder (default: [study] output, else output/<study-stem>): "
                        "new, empty or the study's own (re-running continues it)")
    p.add_argument("--overwrite", action="store_true",
                   help="run the study afresh: its study.csv, study.png and run folders "
                        "in DIR are replaced (only once the study has been planned); "
                        "nothing else there is touched")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_positive_int, metavar="N",
                       help="worker processes of the local cluster (default: one per core)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the Dask cluster at this scheduler (tcp://host:8786)")
    where.add_argument("--serial", action="store_true",
                       help="run the runs one after the other in this process (no Dask)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def _add_convert(sub, options: bool = True) -> None:
    p = sub.add_parser("convert", help="convert a scene between the text and TOML forms")
    if not options:
        return
    p.add_argument("source", help="scene to read (.txt or .toml)")
    p.add_argument("target", help="scene to write (.txt or .toml); not the source itself")
    p.add_argument("--overwrite", action="store_true", help="replace an existing target")


def _add_render(sub, options: bool = True) -> None:
    p = sub.add_parser("render", help="draw a run's frames off screen as PNGs "
                       "(and optionally a GIF or MP4)")
    if not options:
        return
    p.add_argument("folder", metavar="OUT", help="output folder of a run")
    p.add_argument("--every", type=_positive_int, default=1, metavar="K",
                   help="render every K-th of the selected frames (default 1)")
    p.add_argument("--frames", metavar="A:B",
                   help="only frames of steps A <= step < B (either end may be left out)")
    p.add_argument("--gif", action="store_true", help="also write render/animation.gif")
    p.add_argument("--mp4", action="store_true",
                   help="also write render/animation.mp4 (needs imageio and imageio-ffmpeg)")
    p.add_argument("--field", choices=("velocity", "none"), default="none",
                   help="colour by |velocity| instead of by body (default none)")
    p.add_argument("--azimuth", type=_finite_float, default=30.0, metavar="DEG",
                   help="camera angle about the vertical y axis; 0 looks along -z "
                        "(default 30)")
    p.add_argument("--elevation", type=_finite_float, default=20.0, metavar="DEG",
                   help="camera angle above the horizontal (default 20)")
    p.add_argument("--zoom", type=_finite_float, default=1.0, metavar="Z",
                   help="magnify the view that frames the whole run (default 1)")
    p.add_argument("--size", type=int, nargs=2, default=(800, 600), metavar=("W", "H"),
                   help="image size in pixels (default 800 600)")
    p.add_argument("-o", "--output", metavar="DIR", help="image folder (default OUT/render)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def _add_compare(sub, options: bool = True) -> None:
    p = sub.add_parser("compare", help="compare two runs' frames and logs (exit 0 same, "
                       "1 different, 2 cannot compare)")
    if not options:
        return
    p.add_argument("a", metavar="A", help="output folder of the reference run")
    p.add_argument("b", metavar="B", help="output folder of the other run, a folder of "
                   "the original IPC program's <n>.obj files, or a golden reference .json "
                   "(tests/regression/golden/)")
    p.add_argument("--rtol", type=_finite_float, default=1e-6, metavar="R",
                   help="allowed vertex displacement as a fraction of the scene size "
                        "(bounding-box diagonal of A's first frame; default 1e-6)")
    p.add_argument("--atol", type=_finite_float, default=0.0, metavar="A",
                   help="allowed vertex displacement in metres, added to rtol's (default 0)")
    p.add_argument("--plot", metavar="FILE.png", help="chart the differences over time")


_COMMANDS = {"check": _add_check, "run": _add_run, "sweep": _add_sweep,
             "convert": _add_convert, "render": _add_render, "compare": _add_compare}


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings (from libraries or the simulation) as one line each."""
    print(f"warning: {one_line(message)}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser(_command_in(sys.argv[1:] if argv is None else argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error (already printed)
        return exc.code if isinstance(exc.code, int) else 2
    if getattr(args, "command", None) is None:
        print(f"ipcsim: error: give a command: {', '.join(_COMMANDS)} (see ipcsim --help)",
              file=sys.stderr)
        return 2
    if args.command != "run":
        resume_collector()  # a run resumes it once built, before its first step
    try:
        import numpy as np

        # the simulation checks for NaN and infinity itself and names the term; numpy's
        # own overflow warnings would only add lines
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.showwarning = _show_warning
            return int(_command_main(args.command)(args) or 0)
    except IpcsimError as exc:
        text = str(exc) if isinstance(exc, SceneError) else f"ipcsim: {exc}"
        print(one_line(text), file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into a reader that stopped (`| head`)
        sys.stderr = open(os.devnull, "w")
        return 0
    except OSError as exc:  # a write the command did not expect to fail (a full disk)
        where = f"{exc.filename}: " if exc.filename else ""
        print(one_line(f"ipcsim: {where}{exc.strerror or exc}"), file=sys.stderr)
        return 2


def console() -> NoReturn:
    """The ``ipcsim`` command (and ``python -m ipcsim``): ``main`` as a process.

    Every file a command writes is closed before ``main`` returns, so the process then
    ends without the interpreter's teardown (``start_up.end_process``). Where that
    teardown must run (an exit handler, a thread), it would end with a full pass of the
    cycle collector over every object left (numpy's, the modules', the run's), 17 of a
    tiny scene's 24 ms of exit, which finds nothing to finalise: so the objects are
    frozen out of that pass first (``gc.freeze``). Only a process that ends here does
    either (tests call ``main`` many times in one process).

    The collector is also paused while the modules load and the scene is built
    (``ipcsim.start_up``)."""
    pause_collector()
    try:
        status = main()
    finally:
        resume_collector()  # where the command ended before a run's first step
    gc.freeze()
    end_process(status)


if __name__ == "__main__":
    console()
