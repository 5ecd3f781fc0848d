"""README's command table and ``ipcsim --help`` agree: every subcommand has a row, and
every option a row names is one the subcommand takes (for run and sweep, all of them)."""

from __future__ import annotations

import re

from ipcsim import cli
from ipcsim.cli import build_parser


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return action.choices


def test_readme_command_table_matches_the_parser(repo_root):
    readme = (repo_root / "README.md").read_text()
    rows = [ln for ln in readme.splitlines() if ln.startswith("| `ipcsim ")]
    for name, sub in _subparsers().items():
        mine = [re.split(r"(?<!\\)\|", r)[1] for r in rows if r.startswith(f"| `ipcsim {name} ")
                or r.startswith(f"| `ipcsim {name}`")]
        assert mine, f"README has no row for ipcsim {name}"
        text = " ".join(mine)
        named = set(re.findall(r"(?<![\w-])--?[a-z][a-z-]*", text))
        options = {o for a in sub._actions for o in a.option_strings}
        assert named <= options, (name, named - options)
        if name in ("run", "sweep"):  # every option of theirs is in the row
            missing = [a.option_strings for a in sub._actions if a.option_strings
                       and "--help" not in a.option_strings
                       and not set(a.option_strings) & named]
            assert missing == [], (name, missing)


def test_a_commands_own_parser_reads_its_arguments_as_the_whole_parser_does():
    """``main`` builds only the named command's options (``build_parser(command)``):
    its arguments read the same as with every command's options, and every command is
    still listed."""
    examples = {
        "check": ["check", "s.txt", "--set", "time.dt=0.01"],
        "run": ["run", "s.txt", "-o", "out", "--overwrite", "--steps", "3", "-q"],
        "sweep": ["sweep", "study.toml", "--serial"],
        "convert": ["convert", "a.txt", "b.toml", "--overwrite"],
        "render": ["render", "out", "--every", "2", "--size", "640", "480", "--gif"],
        "compare": ["compare", "a", "b", "--rtol", "1e-3"],
    }
    assert set(examples) == set(_subparsers())
    for name, argv in examples.items():
        assert cli._command_in(argv) == name
        own = build_parser(cli._command_in(argv))
        assert set(next(a for a in own._actions if a.dest == "command").choices) \
            == set(examples)
        assert vars(own.parse_args(argv)) == vars(build_parser().parse_args(argv))


def test_no_command_or_an_unknown_one_gets_every_commands_options():
    assert cli._command_in([]) is None
    assert cli._command_in(["--version"]) is None
    assert cli._command_in(["rn", "s.txt"]) is None  # argparse names the choices
    assert cli._command_in(["-h", "run"]) == "run"


def test_no_command_is_one_line_on_stderr(capsys):
    from ipcsim.cli import main

    assert main([]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    assert "give a command: check, run, sweep" in captured.err
