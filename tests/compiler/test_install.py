"""The compiler seam (ipcsim/compiler/build.py): an install that could compile the kernels
ahead of time did, a build is reused for unchanged sources, and without the compiled
module numba compiles the same kernels to the same bits."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ipcsim.compiler import aot, build

ROOT = Path(__file__).resolve().parents[2]


def test_the_install_compiled_the_kernels_where_it_could():
    """Where a C compiler is at hand, an install without its compiled module (numba's
    pycc gone, the build failed, or kernels edited since) fails here rather than running
    every kernel through numba, a minute of compiling at each first run."""
    if os.environ.get("IPCSIM_AOT", "1").strip() == "0":
        pytest.skip("IPCSIM_AOT=0: installed and run without the compiled kernels")
    if build.c_compiler() is None:
        pytest.skip("no C compiler: numba compiles every kernel on first use")
    why_not = build.numba_can_compile_ahead()
    assert why_not is None, f"{why_not}: pin numba to the range in pyproject.toml"
    assert aot.compiled_folder() is not None, (
        "no compiled module fits these kernel sources: install again (pip install .), "
        "or rebuild in place with python -m ipcsim.compiler.build ipcsim/compiler")


def _fake_build(folder: Path, tag: str) -> None:
    folder.mkdir(parents=True)
    (folder / "_compiled.fake.so").write_text(tag)
    (folder / aot.MATCHERS).write_text("matchers " + tag)
    (folder / aot.MANIFEST).write_text(json.dumps({"module_file": "_compiled.fake.so",
                                                   "sources": tag}))


def test_a_build_is_reused_for_the_same_sources_and_not_for_others(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    _fake_build(tmp_path / "first", "A")
    build.into_cache(tmp_path / "first", root)
    assert build.from_cache(tmp_path / "second", root) == tmp_path / "second" / aot.MANIFEST
    for name in ("_compiled.fake.so", aot.MATCHERS, aot.MANIFEST):
        assert (tmp_path / "second" / name).read_bytes() == \
            (tmp_path / "first" / name).read_bytes()
    monkeypatch.setattr(aot, "sources_digest", lambda: "an edited kernel")
    assert build.from_cache(tmp_path / "third", root) is None


def test_a_cached_build_is_copied_without_compiling(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    _fake_build(tmp_path / "first", "A")
    build.into_cache(tmp_path / "first", root)
    monkeypatch.setenv("IPCSIM_BUILD_CACHE", str(root))

    def no_compiling(*_):
        raise AssertionError("compiled although the cache holds the build")

    monkeypatch.setattr(build, "build", no_compiling)
    assert build.main([str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "_compiled.fake.so").read_text() == "A"


def test_an_incomplete_build_is_not_cached(tmp_path):
    _fake_build(tmp_path / "first", "A")
    (tmp_path / "first" / aot.MATCHERS).unlink()
    build.into_cache(tmp_path / "first", tmp_path / "cache")
    assert build.from_cache(tmp_path / "out", tmp_path / "cache") is None


def test_without_the_compiled_module_numba_runs_the_same_kernels_to_the_same_bits(tmp_path):
    """The fallback: IPCSIM_AOT=0 (as where pycc is gone) runs the hello-world scene
    through numba (cached beside the sources), frame for frame as the compiled kernels
    do, and run.json says so."""
    frames = {}
    for name, aot_flag in (("numba", "0"), ("default", "1")):
        out = tmp_path / name
        env = dict(os.environ, IPCSIM_AOT=aot_flag)
        subprocess.run([sys.executable, "-m", "ipcsim", "run", "input/two_cubes_fall.txt",
                        "-o", str(out), "--steps", "2", "-q"], cwd=ROOT, env=env, check=True)
        frames[name] = [f.read_bytes() for f in sorted((out / "frames").glob("*.vtu"))]
        kernels = json.loads((out / "run.json").read_text())["kernels"]
        if name == "numba":
            assert kernels["compiled_ahead_of_time"] is False
            assert "elasticity.tets.elastic_energy" in kernels["run_by_numba"]
    assert len(frames["numba"]) == 3 and frames["numba"] == frames["default"]
