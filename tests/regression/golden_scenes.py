"""The scenes of the golden regression tests, shared by test_golden.py and regenerate.py.

Each is a short run (a few seconds) chosen to reach the code it guards: plane contact,
mesh contact, friction, Newmark, moving Dirichlet vertices. Its reference is
``golden/<name>.json`` (see ``ipcsim.io.compare.golden_from_run``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from examples import IPC_EXAMPLES, REPO_ROOT

from ipcsim.cli import main

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"

# Positions must agree to 1e-6 of the scene size (the bounding-box diagonal of the first
# frame), counts exactly. Another CPU, compiler or BLAS changes the last bits of each
# solve; stand-ins for that (SuperLU instead of CHOLMOD, the time step changed by 1e-13 of
# itself) moved no sampled vertex of these scenes by more than 1e-11 of the scene size and
# changed no count, while the smallest real change tried, Young's modulus times 1 + 1e-4,
# moved vertices by 2e-6 to 3e-4 of it (README.md). Newton iteration counts can be exact
# because the closest any iteration here ends to the threshold ‖p‖∞ = tol is 1 % of it
# (regenerate.py prints it per scene), far above round-off; a contact count flips only if
# a pair sits within round-off of d̂, which none of the trials above hit.
RTOL = 1e-6


@dataclass(frozen=True)
class GoldenScene:
    name: str
    scene: str  # relative to the repository, or to the original's examples folder
    steps: int
    covers: str
    original_example: bool = False

    def path(self) -> Path | None:
        """The scene file, or None when it is an original example that is not present."""
        if not self.original_example:
            return REPO_ROOT / self.scene
        return IPC_EXAMPLES / self.scene if IPC_EXAMPLES.is_dir() else None

    @property
    def golden(self) -> Path:
        return GOLDEN_DIR / f"{self.name}.json"

    def run(self, out: Path) -> int:
        """Run the scene for its steps into ``out`` (as ``ipcsim run``); the exit status."""
        return main(["run", str(self.path()), "-o", str(out), "--steps", str(self.steps),
                     "-q"])


SCENES = [
    GoldenScene("cube_drop", "input/cube_drop.txt", 20,
                "a cube lands on the ground plane (plane contact from step 13)"),
    GoldenScene("two_cubes_fall", "input/two_cubes_fall.txt", 22,
                "the hello-world scene up to just before the cubes meet: two bodies, "
                "friction with the ground from step 18"),
    GoldenScene("tilted_cubes", "tests/regression/scenes/tilted_cubes.txt", 24,
                "a tilted cube lands off centre on another: point-triangle and edge-edge "
                "contact from step 6"),
    GoldenScene("tilted_cubes_friction", "tests/regression/scenes/tilted_cubes_friction.txt",
                24, "the same with friction between the cubes and with the ground"),
    GoldenScene("2cubesFall_NM", "input/tutorialExamples/advanced/2cubesFall_NM.txt", 96,
                "Newmark with Rayleigh damping, frames every second step, ground contact "
                "from step 91", original_example=True),
    GoldenScene("2cubesFall_DBC", "input/tutorialExamples/BC/2cubesFall_DBC.txt", 18,
                "Dirichlet vertices dragging the lower cube's corners apart; the upper "
                "cube lands on it at step 18, with friction",
                original_example=True),
]
