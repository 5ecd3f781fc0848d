from __future__ import annotations

import datetime as dt
import json
import math
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ipcsim
from ipcsim.io.run_info import (RUN_KEYS, environment_info, now_iso, write_run_info)


def test_run_json_has_environment_and_caller_facts(tmp_path):
    start = now_iso()
    path = write_run_info(
        tmp_path,
        {
            "scene": Path("input/two_cubes.toml"),
            "status": "completed",
            "started": start,
            "finished": now_iso(),
            "wall_s": np.float64(12.5),
            "steps_done": np.int64(100),
            "modelled_terms": ("inertia", "gravity", "elasticity", "barrier"),
            "linear_solver": "cholmod",
            "custom": {"dhat": 1e-3, "bad": math.nan},
        },
    )
    assert path == tmp_path / "run.json"
    info = json.loads(path.read_text())
    assert info["ipcsim_version"] == ipcsim.__version__
    assert info["python_version"] == ".".join(map(str, sys.version_info[:3]))
    assert info["numpy_version"] == np.__version__
    for key in ("scipy_version", "numba_version", "platform", "command"):
        assert info[key]
    assert info["scene"] == str(Path("input/two_cubes.toml"))
    assert info["status"] == "completed"
    assert dt.datetime.fromisoformat(info["started"]).tzinfo is not None
    assert info["wall_s"] == 12.5
    assert info["steps_done"] == 100
    assert info["modelled_terms"] == ["inertia", "gravity", "elasticity", "barrier"]
    assert info["linear_solver"] == "cholmod"
    assert info["custom"] == {"dhat": 1e-3, "bad": None}  # strict JSON has no NaN


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
                    reason="platform.platform() names other systems in its own way")
def test_platform_is_platform_platforms_string():
    assert environment_info()["platform"] == platform.platform()


def test_environment_info_starts_no_process():
    # platform.platform() runs `uname -p` in a subprocess: ten milliseconds of every run
    code = ("import sys; from ipcsim.io.run_info import environment_info; "
            "environment_info(); print('subprocess' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_unset_run_keys_are_null_and_caller_wins(tmp_path):
    info = json.loads(write_run_info(tmp_path, {"platform": "mine"}).read_text())
    assert all(info[k] is None for k in RUN_KEYS)
    assert info["platform"] == "mine"


def test_rewriting_updates_in_place(tmp_path):
    write_run_info(tmp_path, {"status": "running"})
    write_run_info(tmp_path, {"status": "failed", "steps_done": 3})
    info = json.loads((tmp_path / "run.json").read_text())
    assert (info["status"], info["steps_done"]) == ("failed", 3)
    assert [p.name for p in tmp_path.iterdir()] == ["run.json"]


def test_unserialisable_value_raises_and_keeps_old_file(tmp_path):
    write_run_info(tmp_path, {"status": "running"})
    with pytest.raises(TypeError):
        write_run_info(tmp_path, {"status": object()})
    assert json.loads((tmp_path / "run.json").read_text())["status"] == "running"


def test_environment_info_is_json_ready():
    env = environment_info()
    assert json.loads(json.dumps(env)) == env



def test_peak_memory_is_the_process_own_high_water_mark():
    """A fresh interpreter that touches 200 MB reports a peak that grew by about that."""
    import subprocess
    import sys

    code = ("import numpy as np; from ipcsim.io.run_info import peak_memory_mb as p; "
            "a = p(); b = np.ones(200 * 2**20 // 8); print(a, p())")
    before, after = map(float, subprocess.run([sys.executable, "-c", code], check=True,
                                              capture_output=True, text=True).stdout.split())
    assert 1.0 < before < 150.0
    assert 190.0 < after - before < 260.0


def test_versions_are_the_installed_distributions():
    """Read from the dist-info folders' names: what importlib.metadata reads too."""
    from importlib import metadata

    from ipcsim.io.run_info import _versions

    dists = ("numpy", "scipy", "meshio", "tomli-w")
    assert _versions(*dists) == {dist: metadata.version(dist) for dist in dists}
    assert _versions("no-such-distribution", "numpy") == {
        "no-such-distribution": None, "numpy": metadata.version("numpy")}
