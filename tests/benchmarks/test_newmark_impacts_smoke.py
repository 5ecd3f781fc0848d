"""benchmarks/newmark_impacts.py, ipcsim alone, two heights."""

from __future__ import annotations

import re

from benchmarks import newmark_impacts


def test_two_drops_report_their_energy_after_the_impacts(tmp_path, capsys):
    assert newmark_impacts.main(["--heights", "2", "--steps", "170", "--no-original",
                                 "--work", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    ratios = [float(r) for r in re.findall(r"ipcsim (\d+\.\d+)$", out, flags=re.M)]
    assert len(ratios) == 2 and all(0.5 < r < 10.0 for r in ratios)
    assert "the original not run (--no-original)" in out


def test_too_few_steps_are_refused(capsys):
    assert newmark_impacts.main(["--steps", "100", "--no-original"]) == 2
    assert "--steps must be at least" in capsys.readouterr().err
