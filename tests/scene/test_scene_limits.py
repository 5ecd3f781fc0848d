"""What a scene reader refuses because no scene means it, and how it quotes a user's text:
every case here was, before it was fixed, a traceback, a hang, a silently wrong value or a
message that blamed something else."""

from __future__ import annotations

import os

import pytest

from ipcsim.errors import SceneError, excerpt
from ipcsim.scene import MAX_SCENE_BYTES, load_scene, parse_toml, parse_txt
from ipcsim.scene.validate import MAX_STEPS

CUBE = "shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1\n"
TOML_CUBE = '[[shapes]]\npath = "meshes/cube.msh"\n'


def refused(load, text, name="scene.txt"):
    with pytest.raises(SceneError) as err:
        load(text, name)
    return err.value


def test_unicode_digits_are_not_numbers(load_text):
    """float() reads '١' (Arabic-Indic one) as 1.0; a scene number is ASCII."""
    err = refused(load_text, "time \u0661 0.025\n" + CUBE)
    assert err.line == 1 and "must be a number" in err.message
    err = refused(load_text, "shapes input \u0661\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1\n")
    assert "whole number" in err.message


def test_a_count_too_large_for_an_integer_is_refused(load_text):
    err = refused(load_text, "fricIterAmt 100000000000000000000\n" + CUBE)
    assert err.line == 1 and "too large" in err.message
    err = refused(load_text, "shapes input " + "9" * 5000 + "\n")  # int() would raise
    assert "too large" in err.message and len(str(err)) < 300


def test_friction_iterations_are_bounded(load_text, write_scene):
    err = refused(load_text, "fricIterAmt 1000000\n" + CUBE)
    assert err.line == 1 and "at most 100" in err.message
    path = write_scene(TOML_CUBE + "[contact]\nfriction_iterations = 100000000000000000000\n",
                       "s.toml")
    with pytest.raises(SceneError, match="at most 100"):
        load_scene(path)
    assert load_text("fricIterAmt -1\n" + CUBE).friction_iterations == -1


def test_a_step_count_that_overflows_is_refused(load_text):
    err = refused(load_text, "time 1e300 1e-10\n" + CUBE)
    assert err.line == 1 and "time steps" in err.message and f"{MAX_STEPS:.0e}" in err.message
    err = refused(load_text, "time 1e300 1e-300\n" + CUBE)  # duration / dt = inf
    assert "time steps" in err.message


@pytest.mark.parametrize("text,line,fragment", [
    ("density 1e300\n" + CUBE, 1, "beyond any material"),
    ("shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1 material 1e300 1e5 0.3\n", 2,
     "beyond any material"),
    ("shapes input 1\nmeshes/cube.msh 0 1e200 0  0 0 0  1 1 1\n", 2, "beyond any scene"),
    ("shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1e200 1e200 1e200\n", 2, "factor beyond"),
    ("ground 0 1e300\n" + CUBE, 1, "beyond any scene"),
    ("meshCO meshes/plane.obj 0 0 0 1e300 0 0\n" + CUBE, 1, "beyond any scene"),
], ids=["density", "shape density", "translation", "scale", "ground", "meshCO size"])
def test_absurd_numbers_are_refused_by_name(load_text, text, line, fragment):
    """density 1e300 used to end as 'a vertex is below the ground', a translation of 1e200
    as 'a tetrahedron is degenerate'."""
    err = refused(load_text, text)
    assert err.line == line and fragment in err.message


def test_a_scene_larger_than_anyone_writes_is_refused_unread(write_scene):
    path = write_scene(CUBE + "\n" * MAX_SCENE_BYTES)
    with pytest.raises(SceneError, match="at most 1 MiB") as err:
        load_scene(path)
    assert err.value.line is None


def test_a_device_is_not_read(tmp_path):
    """A scene named after /dev/zero was read for ever."""
    link = tmp_path / "zero.txt"
    os.symlink("/dev/zero", link)
    with pytest.raises(SceneError, match="not a regular file"):
        load_scene(link)


def test_a_binary_file_is_refused_at_its_first_nul(write_scene):
    path = write_scene(CUBE + "density 1000\n\0\0\0" * 3)
    with pytest.raises(SceneError, match="NUL") as err:
        load_scene(path)
    assert err.value.line == 4


def test_a_huge_token_is_quoted_as_a_short_excerpt(load_text):
    token = "x" * 100_000
    err = refused(load_text, f"{token} 1\n" + CUBE)
    assert len(str(err)) < 300 and excerpt(token) in err.message


def test_a_warning_about_ignored_numbers_names_a_few(load_text):
    spec = load_text("ground 0 0 " + " ".join(["1"] * 200_000) + "\n" + CUBE)
    (warning,) = spec.warnings
    assert "and 199995 more" in warning and len(warning) < 300


def test_a_mesh_path_that_is_a_folder_is_called_a_folder(load_text, scene_dir):
    (scene_dir / "meshes" / "dir.msh").mkdir()
    err = refused(load_text, "shapes input 1\nmeshes/dir.msh 0 0 0  0 0 0  1 1 1\n")
    assert err.line == 2 and "is a folder, not a file" in err.message
    assert "not found" not in err.message


def test_a_mesh_name_too_long_for_the_file_system_is_not_found(load_text):
    err = refused(load_text, "shapes input 1\n" + "m" * 5000 + ".msh 0 0 0 0 0 0 1 1 1\n")
    assert "not found" in err.message and len(str(err)) < 400


@pytest.mark.parametrize("text,fragment", [
    ("a = " + "1" * 5000 + "\n", "invalid TOML"),
    ("a = " + "[" * 5000 + "]" * 5000 + "\n", "invalid TOML"),
    ('[[shapes]]\npath = "' + "p" * 100_000 + '.msh"\n', "not found"),
    ('[material]\nenergy = "' + "E" * 100_000 + '"\n', "must be one of"),
], ids=["huge integer", "deep nesting", "long path", "long string"])
def test_toml_oddities_are_short_scene_errors(text, fragment, tmp_path):
    with pytest.raises(SceneError, match=fragment) as err:
        parse_toml(text, tmp_path / "s.toml")
    assert len(str(err.value)) < 400


def test_blank_and_comment_lines_between_keywords_are_skipped(write_scene):
    """Runs of blank and comment lines are skipped in one search (every line used to be
    split into tokens up front: seconds and hundreds of MB for a few MB of them)."""
    body = ("\n" * 1000 + "# note\n" * 1000 + "  \t \n" * 1000) * 20
    path = write_scene("time 1 0.1\n" + body + "density 900\ntol 1\n" + body + "0.5\n"
                       + CUBE)
    spec = parse_txt(path.read_text(), path)
    assert spec.density == 900 and spec.dt == 0.1 and spec.newton_tol == (0.5,)
    assert spec.shapes[0].line == body.count("\n") * 2 + 6
