"""``ipcsim run SCENE --set KEY=VALUE``: the resolved scene.toml beside the results holds
exactly the overridden values; a bad key or value exits 2 naming it and writes nothing;
``--resume`` continues a run only with the overrides it was started with."""

from __future__ import annotations

import json
import shutil

import msgspec
import pytest

from ipcsim.cli import main
from ipcsim.scene import load_scene


@pytest.fixture
def scene(repo_root, tmp_path):
    shutil.copytree(repo_root / "input" / "meshes", tmp_path / "meshes")
    shutil.copy(repo_root / "input" / "cube_drop.toml", tmp_path / "scene.toml")
    return tmp_path / "scene.toml"


def test_set_changes_exactly_those_values(scene, tmp_path, capsys):
    out = tmp_path / "out"
    sets = ["--set", "time.dt=0.01", "--set", "contact.dhat=1e-3", "--set",
            "shapes.0.material.E=2e5"]
    assert main(["run", str(scene), "-o", str(out), "-q", "--steps", "3", *sets]) == 0
    resolved = load_scene(out / "scene.toml")
    base = load_scene(scene)
    material = msgspec.structs.replace(base.shapes[0], material=msgspec.structs.replace(
        resolved.shapes[0].material, youngs_modulus=2e5))
    assert resolved == msgspec.structs.replace(base, dt=0.01, dhat=1e-3, shapes=(material,))
    assert resolved.shapes[0].material.density == base.density
    assert "# overrides of the scene file's values: time.dt = 0.01" in \
        (out / "scene.toml").read_text()
    info = json.loads((out / "run.json").read_text())
    assert info["overrides"] == {"time.dt": 0.01, "contact.dhat": 1e-3,
                                 "shapes.0.material.E": 2e5}

    # resumed with the same overrides: continues; without them, or others: refused
    again = ["run", str(scene), "-o", str(out), "-q", "--steps", "5", "--resume"]
    assert main(again[:-1] + ["--resume", "--set", "time.dt=0.02"]) == 2
    assert "not the scene the run" in capsys.readouterr().err
    assert main(again) == 2
    capsys.readouterr()
    assert main(again + sets) == 0
    assert json.loads((out / "run.json").read_text())["steps_done"] == 5


@pytest.mark.parametrize("setting, says", [
    ("time.dtt=0.01", "override time.dtt = 0.01: unknown key time.dtt"),
    ("time.dt=fast", "override time.dt = 'fast': time.dt must be a number"),
    ("contact.dhat=-1", "override contact.dhat = -1: contact.dhat must be > 0"),
    ("time.dt", "--set time.dt: expected KEY=VALUE"),
])
def test_a_bad_key_or_value_exits_2_naming_it(scene, tmp_path, capsys, setting, says):
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()
    assert main(["check", str(scene), "--set", setting]) == 2
