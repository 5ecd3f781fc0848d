"""Small generated meshes for tests that write their own scenes."""

from __future__ import annotations

from pathlib import Path

from ipcsim.model.generate import box_tet_mesh, write_msh


def write_box_msh(path, cells=(2, 2, 2), size=(0.2, 0.2, 0.2), base_y=0.0) -> Path:
    """Write a box of ``cells`` (6 tets each) and ``size`` metres to ``path`` (.msh),
    centred on the y axis with its base at height ``base_y``; returns the path."""
    sx, sy, sz = size
    points, tets = box_tet_mesh(*cells, size=size, origin=(-sx / 2, base_y, -sz / 2))
    return write_msh(Path(path), points, tets)



def write_press_scene(folder) -> Path:
    """A cube whose top face is driven down at 0.6 m/s onto a fixed cube just below it
    (h = 0.05 s, no gravity): each step's first iteration is cut short by the contact, so
    the prescribed vertices are pulled to their targets (potentials/boundary_pull.py).
    Writes cube.msh and press.txt into ``folder``; returns the scene's path."""
    folder = Path(folder)
    cube = write_box_msh(folder / "cube.msh", cells=(3, 3, 3))
    scene = folder / "press.txt"
    scene.write_text(
        "shapes input 2\n"
        f"{cube.name} 0 0.205 0  0 0 0  1 1 1  DBC -0.1 0.9 -0.1  1.1 1.1 1.1  0 -0.6 0  0 0 0\n"
        f"{cube.name} 0 0 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 1.1 1.1  0 0 0  0 0 0\n"
        "time 0.15 0.05\nstiffness 1e5 0.4\nturnOffGravity\n")
    return scene

def modules_a_run_imports(scene, out, *args: str) -> tuple[int, set[str]]:
    """Run ``ipcsim run scene -o out -q *args`` in a fresh interpreter: its exit status
    and every module it imported (for the tests that keep imports out of a small scene's
    start)."""
    import subprocess
    import sys

    code = ("import sys\nfrom ipcsim.cli import main\n"
            f"status = main(['run', {str(scene)!r}, '-o', {str(out)!r}, '-q', *{args!r}])\n"
            "print(status, ' '.join(sorted(sys.modules)))\n")
    printed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout.strip().splitlines()[-1]
    status, _, modules = printed.partition(" ")
    return int(status), set(modules.split())


def packages_a_run_imports(scene, out, *args: str) -> tuple[int, set[str]]:
    """The exit status of ``modules_a_run_imports`` and the top-level packages of the
    modules it imported."""
    status, modules = modules_a_run_imports(scene, out, *args)
    return status, {m.split(".")[0] for m in modules}
