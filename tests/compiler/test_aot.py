"""Kernels compiled ahead of time (ipcsim/compiler/aot.py): a call finds its compiled
variant only for the argument types numba would compile it for, the module is used only
with the sources and on a CPU it was built for, it gives numba's bits, and the example
scenes need no other kernel (so a run neither imports numba nor compiles)."""

from __future__ import annotations

import csv
import json
import os
import platform
import subprocess
import sys
import types
from typing import ClassVar

import numpy as np
import pytest
from examples import IPC_EXAMPLES
from generated import write_press_scene

from ipcsim.compiler import aot

COMPILED = aot.compiled_folder() is not None
needs_compiled = pytest.mark.skipif(
    not COMPILED, reason="ipcsim is installed without its compiled kernels (IPCSIM_AOT=0, "
                         "or they could not be built): numba compiles every kernel")


def _samples():
    a = np.zeros((4, 3))
    readonly = np.zeros(3)
    readonly.flags.writeable = False
    return [
        (a, ("float64", 2)), (np.zeros(5, np.int64), ("int64", 1)),
        (np.zeros((2, 3, 3)), ("float64", 3)), (np.zeros(2, np.int32), ("int32", 1)),
        (np.zeros(2, bool), ("bool", 1)), (1.5, "float64"), (3, "int64"), (True, "bool"),
        (np.float64(2.0), "float64"), (np.int64(7), "int64"), (np.bool_(False), "bool"),
        ((a, np.zeros((4, 2), np.int64), 2), (("float64", 2), ("int64", 2), "int64")),
        (readonly, None), (a[:, ::2], None), (np.asfortranarray(a), None),
        (np.zeros(3, np.complex128), None), ("text", None), (None, None),
    ]


@pytest.mark.parametrize("value, key", _samples(), ids=lambda v: type(v).__name__)
def test_argument_types_are_keyed_as_numba_types_them(value, key):
    """Where a key is given it names exactly the type numba infers, so a compiled
    variant runs only where numba would run that very specialisation; every other
    argument (read-only, strided, Fortran-ordered, of another type) has no key."""
    assert aot.argument_types((value,)) == (key,)
    if key is not None:
        from numba import typeof

        from ipcsim.compiler.build import _numba_type
        assert _numba_type(key) == typeof(value)


def _value_of(key, rng):
    """An argument whose key is ``key``."""
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[1], int):
        dtype, ndim = key
        return np.zeros((2,) * ndim, dtype=dtype)
    if isinstance(key, tuple):
        return tuple(_value_of(k, rng) for k in key)
    return {"float64": float(rng.random()), "int64": int(rng.integers(9)), "bool": True,
            "float32": np.float32(1), "int32": np.int32(1), "uint8": np.uint8(1),
            "int8": np.int8(1)}[key]


def _near_misses(args):
    """The arguments with one of them changed as a call might change it: another
    dtype, read-only, strided, Fortran-ordered, a Python int for a float, one more or
    one fewer argument, a tuple one item short, numpy scalars for Python ones."""
    yield args + (1.0,)
    yield args[:-1]
    for i, a in enumerate(args):
        for b in _variants(a):
            yield args[:i] + (b,) + args[i + 1:]


def _variants(a):
    if isinstance(a, np.ndarray):
        yield a.astype(np.float32 if a.dtype == np.float64 else np.float64)
        readonly = a.copy()
        readonly.flags.writeable = False
        yield readonly
        if a.ndim:
            yield np.repeat(a, 2, axis=0)[::2]
        if a.ndim == 2:
            yield np.asfortranarray(np.zeros((2, 3), a.dtype))
        yield a.reshape(-1) if a.ndim > 1 else a.reshape(1, -1)
    elif isinstance(a, tuple):
        yield a[:-1]
        yield list(a)
        for i, item in enumerate(a):
            for b in _variants(item):
                yield a[:i] + (b,) + a[i + 1:]
    else:
        yield np.float64(a) if isinstance(a, float) else np.int64(a) \
            if isinstance(a, int) and not isinstance(a, bool) else np.bool_(a)
        yield 1 if isinstance(a, float) else 1.0
        yield None


def test_the_generated_matcher_answers_as_the_keyed_lookup():
    """On every signature of the table, with all of them compiled into one entry table
    per kernel: exact arguments match their own function, and every near miss gets
    exactly what ``entries.get(argument_types(args))`` gives (mostly None)."""
    rng = np.random.default_rng(5)
    kernels = {}
    for module, function, key in aot.read_table():
        kernels.setdefault((module, function), {})[key] = object()
    checked = 0
    for entries in kernels.values():
        match = aot.matcher(entries)
        for key, function in entries.items():
            args = tuple(_value_of(k, rng) for k in key)
            assert aot.argument_types(args) == key
            assert match(args) is function
            for other in _near_misses(args):
                assert match(other) is entries.get(aot.argument_types(other))
                checked += 1
    assert checked > 1000
    assert aot.matcher(None)((np.zeros(3),)) is None


def test_stored_matchers_answer_as_the_ones_compiled_at_the_first_call(tmp_path,
                                                                          monkeypatch):
    """The build stores each kernel's matcher code (``store_matchers``); a matcher made
    from it answers every signature and near miss as one compiled on the spot, and the
    stored code is used only for entries with the same keys in the same order."""
    rng = np.random.default_rng(7)
    kernels = {}
    for module, function, key in aot.read_table():
        kernels.setdefault((module, function), []).append(key)
    aot.store_matchers(tmp_path, kernels)
    stored = aot._stored_matchers(tmp_path)
    assert set(stored) == set(kernels)
    monkeypatch.setitem(aot._loaded, "matchers", stored)
    for (module, function), keys in kernels.items():
        py_func = types.SimpleNamespace(__module__=f"ipcsim.kernels.{module}",
                                        __name__=function)
        entries = {key: object() for key in keys}
        code = aot.stored_matcher_code(py_func, entries)
        assert code is not None
        from_store, compiled = aot.matcher(entries, code), aot.matcher(entries)
        for key, function_ in entries.items():
            args = tuple(_value_of(k, rng) for k in key)
            assert from_store(args) is compiled(args) is function_
            for other in _near_misses(args):
                assert from_store(other) is compiled(other)
        if len(keys) > 1:  # another order: the stored code would return the wrong one
            assert aot.stored_matcher_code(py_func, dict(reversed(entries.items()))) is None
    other = types.SimpleNamespace(__module__="ipcsim.kernels.none", __name__="none")
    assert aot.stored_matcher_code(other, {(("float64", 1),): len}) is None


def test_matchers_stored_by_another_python_are_not_read(tmp_path):
    aot.store_matchers(tmp_path, {("m", "f"): [(("float64", 1),)]})
    assert set(aot._stored_matchers(tmp_path)) == {("m", "f")}
    path = tmp_path / aot.MATCHERS
    path.write_bytes(b"\x00\x00\r\n" + path.read_bytes()[4:])  # another bytecode magic
    assert aot._stored_matchers(tmp_path) == {}
    aot.store_matchers(tmp_path, {("m", "f"): [(("float64", 1),)]})
    path.write_bytes(path.read_bytes()[:40])  # cut short
    assert aot._stored_matchers(tmp_path) == {}
    assert aot._stored_matchers(tmp_path / "none") == {}


def test_every_table_line_reads_back_as_written():
    lines = [line for line in aot.TABLE.read_text(encoding="utf-8").splitlines()
             if line and not line.startswith("#")]
    rows = aot.read_table()
    assert len(rows) == len(lines) > 20
    for line, (module, function, key) in zip(lines, rows):
        assert f"{module}.{function}({', '.join(aot.format_key(k) for k in key)})" == line
    assert len(set(lines)) == len(lines)


def test_every_table_key_goes_through_the_manifests_json_unchanged():
    keys = [key for _, _, key in aot.read_table()]
    assert any(isinstance(k, tuple) and not isinstance(k[1], int) for key in keys for k in key)
    for key in keys:
        stored = json.loads(json.dumps([aot.key_to_json(k) for k in key]))
        assert tuple(aot.key_from_json(k) for k in stored) == key


def test_the_machine_is_named_as_platform_names_it():
    # aot.uname answers without importing platform (1.3 ms of a start); run.json asks it too
    assert aot.uname() == tuple(platform.uname())[:5]
    assert aot.machine() == platform.machine()


def _manifest(tmp_path, **changes) -> dict:
    manifest = {"sources": aot.sources_digest(), "machine": platform.machine(),
                "cpu_features": aot.cpu_features()[:3], "module_file": "none.so",
                "exports": []}
    manifest.update(changes)
    (tmp_path / aot.MANIFEST).write_text(json.dumps(manifest))
    return manifest


def test_a_compiled_module_serves_only_its_own_sources_on_a_cpu_with_its_features(tmp_path):
    assert aot._usable(tmp_path) is None  # no manifest
    assert aot._usable(tmp_path) is None
    _manifest(tmp_path, sources="0" * 64)  # built from other kernel sources
    assert aot._usable(tmp_path) is None
    _manifest(tmp_path, cpu_features=["avx-from-the-future"])  # for another CPU
    assert aot._usable(tmp_path) is None
    _manifest(tmp_path, machine="pdp11")
    assert aot._usable(tmp_path) is None
    good = _manifest(tmp_path)
    assert aot._usable(tmp_path) == good


def test_an_installed_module_is_found_from_a_checkout_of_the_same_sources(tmp_path,
                                                                         monkeypatch):
    """Tests run the checkout's sources while ``pip install .`` put the compiled module
    beside the installed copy: it is found on the import path (and used if its manifest
    fits, ``_usable``), not beside these sources."""
    installed = tmp_path / "site" / "ipcsim" / "compiler"
    installed.mkdir(parents=True)
    _manifest(installed)
    monkeypatch.setattr(sys, "path", [str(tmp_path / "nothing"), str(tmp_path / "site")])
    assert list(aot._installed_folders()) == [installed.resolve()]
    assert aot._usable(installed) is not None


def test_importing_the_kernels_and_the_simulation_loads_no_numba():
    """numba is imported only when a kernel must be compiled (jit.numba_module)."""
    code = ("import importlib, pkgutil, sys, ipcsim.kernels as k\n"
            "for m in pkgutil.walk_packages(k.__path__, 'ipcsim.kernels.'):\n"
            "    importlib.import_module(m.name)\n"
            "import ipcsim.simulation, ipcsim.runner, ipcsim.cli\n"
            "print('numba' in sys.modules)\n")
    env = dict(os.environ, IPCSIM_AOT="0")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True).stdout.split()
    assert out == ["False"]


def test_the_sources_digest_covers_every_kernel_source_and_the_table():
    names = {p.relative_to(aot.KERNELS).as_posix() for p in aot.KERNELS.rglob("*.py")}
    assert {"elasticity/tets.py", "contact/pair_barrier.py", "terms/all_terms.py"} <= names
    assert len(aot.sources_digest()) == 64


@needs_compiled
def test_compiled_kernels_give_numbas_bits():
    """The compiled serial variants against numba's own, on the kernels with the most
    arithmetic: elasticity's Hessian, the contact barrier's, friction's, CCD."""
    from ipcsim.kernels.contact import ccd
    from ipcsim.kernels.contact import pair_barrier as cb
    from ipcsim.kernels.elasticity import tets as el

    rng = np.random.default_rng(3)
    x = rng.random((40, 3))
    tets = np.ascontiguousarray(rng.permutation(40)[:32].reshape(8, 4)).astype(np.int64)
    Dm_inv = rng.random((8, 3, 3)) + np.eye(3)
    vol, lame = rng.random(8) + 0.1, rng.random((8, 2)) + 0.5
    pt = rng.permutation(40)[:24].reshape(6, 4).astype(np.int64)
    ee = rng.permutation(40)[:16].reshape(4, 4).astype(np.int64)
    eps = np.full(4, 1e-3)
    calls = [
        (el.elastic_hessian_values, (x, tets, Dm_inv, vol, lame, 0, True)),
        (el.elastic_energy, (x, tets, Dm_inv, vol, lame, 1)),
        (cb.barrier_hessian_blocks, (x, pt, ee, eps, 0.09, 1.0, True)),
        (cb.classify_and_distance, (x, pt, ee)),
    ]
    for kernel, args in calls:
        assert kernel.compiled.get(aot.argument_types(args)) is not None, kernel.__name__
        compiled, jitted = kernel(*args), kernel.variant(False)(*args)
        for a, b in zip(compiled if isinstance(compiled, tuple) else (compiled,),
                        jitted if isinstance(jitted, tuple) else (jitted,)):
            np.testing.assert_array_equal(a, b)
    x1 = x + 0.3 * rng.standard_normal(x.shape)
    stencils = np.concatenate([pt, ee])
    state = np.empty((len(stencils), 5))
    state_jit = state.copy()
    ccd.init_queries(x, x1, stencils, len(pt), state)
    ccd.init_queries.variant(False)(x, x1, stencils, len(pt), state_jit)
    np.testing.assert_array_equal(state, state_jit)


SCENES = [("input/two_cubes_fall.txt", 40),
          (IPC_EXAMPLES / "input" / "tutorialExamples" / "2cubesFall.txt", None)]


def _runs_without_numba(scene, steps, out) -> None:
    """Every kernel call of the run (and of the frames' intersection checks) has its
    compiled variant: numba is never imported. Nor is scipy.sparse: the Newton matrix is
    ipcsim's own CSC (solver/assembly.CscMatrix)."""
    code = ("import sys, ipcsim\n"
            "from ipcsim.contact.frame_check import check_frames\n"
            f"ipcsim.run(ipcsim.load_scene({str(scene)!r}), {str(out)!r}, "
            f"steps={steps}, mode='overwrite')\n"
            f"check_frames(__import__('pathlib').Path({str(out)!r}), out=sys.stderr)\n"
            "from ipcsim.compiler import aot\n"
            "print(aot.jit_kernels(), 'numba' in sys.modules, 'scipy.sparse' in sys.modules)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("IPCSIM_AOT", "IPCSIM_THREADS")}
    printed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env=env, check=True).stdout.strip().splitlines()[-1]
    assert printed == "[] False False"
    info = json.loads((out / "run.json").read_text())
    assert info["kernels"] == {"compiled_ahead_of_time": True, "run_by_numba": [],
                               "numba_compile_s": 0.0}


@needs_compiled
@pytest.mark.parametrize("scene, steps", SCENES, ids=["hello world", "2cubesFall"])
def test_the_example_scenes_run_without_numba(scene, steps, tmp_path):
    """Contact, friction, the initial and the frames' intersection checks."""
    if not os.path.exists(scene):
        pytest.skip("the original's examples are not beside the project")
    _runs_without_numba(scene, steps, tmp_path / "out")


@needs_compiled
def test_a_run_that_pulls_prescribed_vertices_runs_without_numba(tmp_path):
    """A cube's top face driven down onto another cube: each step's first iteration is
    cut short by the contact, and the prescribed vertices are pulled to their targets
    (potentials/boundary_pull.py), whose Hessian is a kernel of its own. Without its
    compiled variant numba was imported mid-run: about 120 MB more peak memory on the
    paper's tb1 rods and pencil."""
    scene = write_press_scene(tmp_path)
    _runs_without_numba(scene, None, tmp_path / "out")


@needs_compiled
def test_a_run_with_contacts_leaves_scipy_linalg_unimported(tmp_path):
    """A run whose contacts need the barrier's eigen-decompositions (the kernels' own,
    ``linalg.symmetric_eigen``) leaves scipy.linalg unimported (0.15 s of imports), and
    its frames are those of the same run in a process that imported it."""
    scene = IPC_EXAMPLES / "input" / "tutorialExamples" / "2cubesFall.txt"
    if not os.path.exists(scene):
        pytest.skip("the original's examples are not beside the project")
    env = {k: v for k, v in os.environ.items() if k not in ("IPCSIM_AOT", "IPCSIM_THREADS")}
    folders = {}
    for name, first in (("alone", ""), ("with scipy.linalg", "import scipy.linalg\n")):
        out = folders[name] = tmp_path / name.replace(" ", "_")
        code = (f"import sys\n{first}from ipcsim.cli import main\n"
                f"status = main(['run', {str(scene)!r}, '-o', {str(out)!r}, '--steps', '60', "
                "'-q'])\n"
                "print(status, 'scipy.linalg' in sys.modules)\n")
        printed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                 env=env, check=True).stdout.strip().splitlines()[-1]
        assert printed == ("0 False" if not first else "0 True")
    with open(folders["alone"] / "steps.csv", newline="") as f:
        contacts = [int(row["contacts_total"]) for row in csv.DictReader(f)]
    assert max(contacts) > 0, "no contact: the barrier's eigh never ran"
    for frame in sorted((folders["alone"] / "frames").glob("*.vtu")):
        assert frame.read_bytes() == (folders["with scipy.linalg"] / "frames" /
                                      frame.name).read_bytes()


def test_a_kernels_matcher_is_made_at_its_first_call():
    """``match_on_first_call`` answers the first call as the generated matcher does and
    leaves that matcher in its place for the calls after it."""
    class Owner:
        compiled: ClassVar = {(("float64", 1),): len}
        py_func = types.SimpleNamespace(__module__="ipcsim.kernels.none", __name__="none")

    owner = Owner()
    owner.match = aot.match_on_first_call(owner)
    stand_in = owner.match
    assert owner.match((np.zeros(3),)) is len
    assert owner.match is not stand_in
    assert owner.match((np.zeros(3),)) is len and owner.match((np.zeros(3, int),)) is None
