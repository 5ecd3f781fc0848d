"""``ipcsim run SCENE [--set KEY=VALUE ...]``: read the scene, apply the overrides and
hand it to :func:`ipcsim.runner.run`, which ``ipcsim.run`` is too; this module only turns
the command line into its arguments and prints what it reports."""

from __future__ import annotations

import sys

from ..errors import IpcsimError, excerpt


def overrides_of(assignments, where="--set") -> dict:
    """``--set KEY=VALUE`` arguments as an overrides mapping (a later KEY wins)."""
    from ..scene import parse_assignment

    out = {}
    for text in assignments or ():
        try:
            key, value = parse_assignment(text)
        except ValueError as exc:
            raise IpcsimError(f"{where} {excerpt(text, 80)}: {exc}") from None
        out[key] = value
    return out


def _print_iteration(it: dict) -> None:
    print(f"  step {it['step']} it {it['iteration']}: alpha={it['alpha']:.3g} "
          f"|p|={it['step_inf_norm']:.3e} tol={it['tolerance']:.3e} "
          f"contacts={it['contacts_total']} kappa={it['kappa']:.3g}", flush=True)


def reporter_for(args):
    """The CLI's reporter: lines and progress unless -q, iterations with -v."""
    from ..runner import Reporter
    from ..io.progress import RunProgress

    quiet = bool(args.quiet)
    return Reporter(
        say=(lambda m: None) if quiet else (lambda m: print(m, flush=True)),
        warn=lambda m: print(m, file=sys.stderr, flush=True),
        progress=RunProgress.mode_for(quiet),
        on_iteration=_print_iteration if args.verbose and not quiet else None,
        scene_name=str(args.scene), command=tuple(sys.argv))


def load(args):
    """The scene of ``args.scene`` with the ``--set`` overrides applied."""
    from ..scene import load_scene

    return load_scene(args.scene, overrides_of(getattr(args, "set", None)))


def main(args) -> int:
    from ..runner import run

    if not args.quiet:
        _tell_when_compiling()
    spec = load(args)
    mode = "resume" if args.resume else ("overwrite" if args.overwrite else "new")
    run(spec, args.output, steps=args.steps, mode=mode, render=args.render,
        reporter=reporter_for(args))
    return 0


def _tell_when_compiling() -> None:
    """Say once why a first run after installing is slow (numba compiles the kernels)."""
    from ..compiler.compiling import when_compiling_starts

    when_compiling_starts(lambda: print(
        "ipcsim: compiling the numba kernels for this machine (once after installing; "
        "later runs start at once)", file=sys.stderr, flush=True))
