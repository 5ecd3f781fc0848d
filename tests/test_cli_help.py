"""README's command table and ``ipcsim --help`` agree: every subcommand has a row, and
every option a row names is one the subcommand takes (for run and sweep, all of them)."""

from __future__ import annotations

import re

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
