from __future__ import annotations

from pathlib import Path

import pytest

from ipcsim.errors import IpcsimError
from ipcsim.io.output_folder import (
    OutputFolderError,
    default_output_folder,
    prepare_output_folder,
)


def test_default_folder_is_output_scene_stem():
    assert default_output_folder("input/paper/twoCubes.txt") == Path("output") / "twoCubes"
    assert default_output_folder(Path("a.b.toml")) == Path("output") / "a.b"
    assert not default_output_folder("x.toml").is_absolute()


def test_new_and_empty_folders_are_prepared(tmp_path):
    out = prepare_output_folder(tmp_path / "new" / "run", overwrite=False)
    assert out == tmp_path / "new" / "run"
    assert (out / "frames").is_dir()
    empty = tmp_path / "empty"
    empty.mkdir()
    prepare_output_folder(empty, overwrite=False)
    assert (empty / "frames").is_dir()


def fill_with_a_run(folder: Path) -> None:
    (folder / "frames").mkdir(parents=True)
    for name in ("frame_000000.vtu", "frame_000001.vtu", "series.pvd", ".series.pvd.tmp-123"):
        (folder / "frames" / name).write_text("x")
    for name in ("steps.csv", "newton.csv", "run.json", "scene.toml", ".run.json.tmp-9"):
        (folder / name).write_text("x")


def test_existing_folder_is_refused_without_overwrite(tmp_path):
    fill_with_a_run(tmp_path)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    with pytest.raises(OutputFolderError, match="exists; pass --overwrite") as err:
        prepare_output_folder(tmp_path, overwrite=False)
    assert str(tmp_path) in str(err.value)
    assert isinstance(err.value, IpcsimError)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_folder_with_only_user_files_is_refused_too(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(OutputFolderError):
        prepare_output_folder(tmp_path, overwrite=False)


def test_overwrite_removes_only_ipcsim_files(tmp_path):
    fill_with_a_run(tmp_path)
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "renders").mkdir()
    (tmp_path / "renders" / "shot.png").write_text("mine")
    (tmp_path / "frames" / "view.pvsm").write_text("mine")
    prepare_output_folder(tmp_path, overwrite=True)
    left = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*"))
    kept = ["frames", "frames/view.pvsm", "notes.txt", "renders", "renders/shot.png"]
    assert left == sorted(kept)


def test_a_file_in_the_way_is_refused(tmp_path):
    target = tmp_path / "out"
    target.write_text("not a folder")
    with pytest.raises(OutputFolderError, match="not a folder"):
        prepare_output_folder(target, overwrite=True)
    assert target.read_text() == "not a folder"


# ----------------------------------------------------------------------------- resolving

from ipcsim.io.output_folder import resolve_output_folder  # noqa: E402


def test_default_folder_takes_append_str_and_refuses_a_dot_stem():
    assert default_output_folder("a/run.txt", "v2") == Path("output") / "run_v2"
    for name in ("...txt", "..toml", "a/...ipc"):
        with pytest.raises(OutputFolderError, match="cannot name an output folder"):
            default_output_folder(name)


def test_resolving_normalises_before_checking(tmp_path, monkeypatch):
    fill_with_a_run(tmp_path / "old")
    scene = tmp_path / "scenes" / "s.txt"
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputFolderError, match="old exists"):
        resolve_output_folder("missing/../old", scene, mode="new")
    assert not (tmp_path / "missing").exists()
    assert resolve_output_folder("missing/../old", scene, mode="overwrite") == tmp_path / "old"
    assert resolve_output_folder("new/run", scene, mode="new") == tmp_path / "new" / "run"
    assert not (tmp_path / "new").exists()  # resolving writes nothing


@pytest.mark.parametrize("where", [".", "..", "scenes", "scenes/.."])
def test_the_current_and_the_scene_folder_and_those_above_are_refused(tmp_path, monkeypatch,
                                                                       where):
    (tmp_path / "scenes").mkdir()
    work = tmp_path / "scenes" / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    with pytest.raises(OutputFolderError, match="current directory|scene's folder"):
        resolve_output_folder(tmp_path / where if where != "." else ".",
                              tmp_path / "scenes" / "s.txt", mode="overwrite")


def test_resume_needs_an_existing_folder_and_may_be_the_scenes(tmp_path):
    with pytest.raises(OutputFolderError, match="no such output folder"):
        resolve_output_folder(tmp_path / "none", tmp_path / "s.txt", mode="resume")
    assert resolve_output_folder(tmp_path, tmp_path / "scene.toml", mode="resume") == tmp_path


def test_a_folder_under_a_file_cannot_be_created(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputFolderError, match="not a folder"):
        resolve_output_folder(tmp_path / "f" / "run", tmp_path / "s" / "s.txt", mode="new")
