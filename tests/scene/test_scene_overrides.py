"""Overrides by dotted TOML key: exactly the named values change, for either format; a bad
key or value is a SceneError naming it, checked as the same value in a TOML file is."""

from __future__ import annotations

import pytest

from ipcsim.errors import SceneError
from ipcsim.scene import load_scene, parse_assignment
from ipcsim.scene.overrides import normalise_key
from ipcsim.scene.toml_writer import scene_to_dict


def _changed(a, b) -> dict:
    """Dotted keys whose resolved values differ between two scenes."""
    def flat(doc, prefix=""):
        if isinstance(doc, dict):
            for k, v in doc.items():
                yield from flat(v, f"{prefix}.{k}" if prefix else k)
        elif isinstance(doc, list) and doc and isinstance(doc[0], dict):
            for i, v in enumerate(doc):
                yield from flat(v, f"{prefix}[{i}]")
        else:
            yield prefix, doc
    fa = dict(flat(scene_to_dict(a, a.source.parent)))
    fb = dict(flat(scene_to_dict(b, b.source.parent)))
    return {k: fb.get(k) for k in fa.keys() | fb.keys() if fa.get(k) != fb.get(k)}


@pytest.mark.parametrize("name", ["cube_drop.toml", "cube_drop.txt", "two_cubes_fall.txt"])
def test_exactly_the_named_values_change(repo_root, name):
    path = repo_root / "input" / name
    base = load_scene(path)
    spec = load_scene(path, {"time.dt": 0.01, "contact.dhat": 2e-3,
                             "shapes.0.material.E": 1e6})
    assert _changed(base, spec) == {
        "time.dt": 0.01, "contact.dhat": 2e-3,
        "contact.dhat_start": 2e-3,  # written out as dhat: no homotopy, as before
        "shapes[0].material.density": base.density,  # a copy of the scene's material
        "shapes[0].material.youngs_modulus": 1e6,
        "shapes[0].material.poisson_ratio": base.poisson_ratio}
    assert spec.dhat_start is None  # no homotopy: it follows the new dhat
    assert spec.overrides == {"time.dt": 0.01, "contact.dhat": 2e-3,
                              "shapes.0.material.E": 1e6}
    assert load_scene(path, {"time.dt": base.dt}) == base
    assert spec.shapes[0].line == base.shapes[0].line  # errors still name the file's line


def test_keys_and_aliases():
    assert normalise_key("shapes.0.material.E") == "shapes[0].material.youngs_modulus"
    assert normalise_key("shapes[2].dbc[1].time_range") == "shapes[2].dbc[1].time_range"
    assert normalise_key("material.nu") == "material.poisson_ratio"
    assert normalise_key("material.rho") == "material.density"
    assert parse_assignment("time.dt=1e-3") == ("time.dt", 1e-3)
    assert parse_assignment("material.energy=FCR") == ("material.energy", "FCR")
    assert parse_assignment('contact.kappa="adaptive"') == ("contact.kappa", "adaptive")
    assert parse_assignment("shapes.0.translation=[0, 1, 0]")[1] == [0, 1, 0]
    with pytest.raises(ValueError):
        parse_assignment("time.dt")


def test_whole_values_and_tables(repo_root):
    path = repo_root / "input" / "cube_drop.toml"
    spec = load_scene(path, {"shapes.0.translation": [0, 0.7, 0], "planes.0.friction": 0.2,
                             "material.nu": 0.3, "integrator.type": "NM"})
    assert spec.shapes[0].translation == (0.0, 0.7, 0.0)
    assert spec.planes[0].friction == 0.2 and spec.poisson_ratio == 0.3
    assert spec.integrator == "NM"


@pytest.mark.parametrize("key, value, says", [
    ("time.dtt", 0.01, "override time.dtt = 0.01: unknown key time.dtt (did you mean 'dt'?)"),
    ("time.dt", "fast", "override time.dt = 'fast': time.dt must be a number"),
    ("time.dt", -1.0, "override time.dt = -1.0: time.dt must be > 0"),
    ("contact.dhat", True, "override contact.dhat = True: contact.dhat must be a number"),
    ("shapes.3.material.E", 1e6, "override shapes.3.material.E: the scene has 1 shapes entry"),
    ("shapes.0.material.E", 0.0, "shapes[0].material.youngs_modulus must be > 0"),
    ("shapes.0.material.stiffness", 1.0, "unknown key shapes[0].material.stiffness"),
    ("time.dt.value", 1.0, "override time.dt.value: time.dt is a value, not a table"),
    ("solver.linear_solver", "magic", "solver.linear_solver must be \"auto\" or one of"),
    ("nonsense.key", 1, "override nonsense.key = 1: unknown key nonsense"),
    ("time..dt", 1, "override 'time..dt': 'time..dt' is not a dotted key"),
])
def test_a_bad_key_or_value_is_a_scene_error_naming_it(repo_root, key, value, says):
    path = repo_root / "input" / "cube_drop.txt"
    with pytest.raises(SceneError) as info:
        load_scene(path, {key: value})
    assert says in str(info.value)
    assert str(info.value).startswith(str(path))
