"""Kernels compiled ahead of time: found, checked and looked up by argument types.

Installing ipcsim compiles the serial variant of every kernel a scene calls from Python,
for the argument types listed in ``signatures.txt``, into one extension module
(``_compiled*.so``, built by ``build.py``), with a manifest beside it
(``_compiled.json``): the digest of the kernel sources it was built from, the CPU
features it was built for, and which export is which kernel for which argument types;
and the compiled code of each kernel's argument matcher (``_compiled.matchers``).
A run then needs neither numba nor its cache for those calls: no compiling on a first
run, and no second of loading numba at every start.

The compiled module is used only when its sources digest equals that of the kernels
being run (edit a kernel and it is out of date: numba compiles that run's kernels, and
``pip install .`` builds them again) and this CPU has every feature it was built for.
It is looked for beside these sources, then in the installed ipcsim (a test run from a
checkout of the same sources). ``IPCSIM_AOT=0`` turns it off.

Argument types are keyed as numba types them, for the types the table can hold: a
C-contiguous, writeable, aligned array is ``(dtype name, ndim)``; int, float and bool
(Python or numpy scalars) are ``"int64"``, ``"float64"``, ``"bool"``; a tuple is the
tuple of its items' keys. Anything else has no compiled match and goes to numba.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
KERNELS = HERE.parent / "kernels"  # the sources compiled
TABLE = HERE / "signatures.txt"
MODULE_NAME = "_compiled"
MANIFEST = f"{MODULE_NAME}.json"
MATCHERS = f"{MODULE_NAME}.matchers"  # the compiled code of the matchers (store_matchers)

_NUMBERS = ("float64", "int64", "int32", "bool", "float32", "uint8", "int8")
_DTYPES = {np.dtype(name): name for name in _NUMBERS}  # dtype.name is slow (microseconds)
_SCALARS = {int: "int64", float: "float64", bool: "bool",
            **{np.dtype(name).type: name for name in _NUMBERS}}


def argument_types(args) -> tuple:
    """The key of a call's arguments (module docstring); ``None`` items never match."""
    return tuple(map(_key, args))


def _key(a):
    t = type(a)
    if t is np.ndarray:
        if a.flags.carray:  # C-contiguous, aligned and writeable
            dtype = _DTYPES.get(a.dtype)
            return None if dtype is None else (dtype, a.ndim)
        return None
    if t is tuple:
        return tuple(map(_key, a))
    return _SCALARS.get(t)


def matcher(entries: dict | None, code=None):
    """``match(args)``: the function of ``entries`` (argument key -> compiled function)
    whose key is ``argument_types(args)``, else None; the same answer as
    ``entries.get(argument_types(args))`` in a fraction of its time (a kernel call from
    Python pays it every time: tens of thousands of calls in a tiny scene's run).
    ``code`` is ``matcher_code(tuple(entries))`` where it was stored at the build.

    It is generated as one chain of tests per key, e.g. for ``(("float64", 2), "int64")``::

        if n == 2 and (type(v0 := args[0]) is ndarray and (v0.dtype is d_float64
                or v0.dtype == d_float64) and v0.ndim == 2 and v0.flags.carray)
                and type(args[1]) in s_int64:
            return f0
    """
    if not entries:
        return _no_match
    namespace = dict(_MATCH_NAMES)
    passed = namespace["passed"] = {}  # the last tuple that passed each tuple test

    def keep(slot, value):
        passed[slot] = value
        return True

    namespace["keep"] = keep
    namespace.update((f"f{i}", function) for i, function in enumerate(entries.values()))
    exec(code or matcher_code(tuple(entries)), namespace)  # noqa: S102
    return namespace["match"]


def matcher_code(keys: tuple):
    """The compiled ``def match(args)`` of ``matcher``, testing ``keys`` in order (the
    i-th returns ``f{i}``). Compiling it takes most of the time of making a matcher
    (2–3 ms for the fused Newton iterations' key), so the build stores it
    (``store_matchers``)."""
    names = (f"v{i}" for i in itertools.count())  # each value is looked up once
    lines = ["def match(args):", "    n = len(args)"]
    slots = itertools.count()
    for i, key in enumerate(keys):
        tests = [f"n == {len(key)}"] + [_argument_test(j, k, names, slots)
                                        for j, k in enumerate(key)]
        lines += [f"    if {' and '.join(tests)}:", f"        return f{i}"]
    lines.append("    return None")
    return compile("\n".join(lines), "<aot.matcher>", "exec")


def _argument_test(j: int, key, names, slots) -> str:
    """``_test`` of argument j; a tuple argument that passed is remembered, and the same
    tuple object passes again without its items being tested (a tuple's items are the
    same objects for its whole life: the kernels' data tuples, made once per time step
    and passed at every call, hold some 40 arrays)."""
    test = _test(f"args[{j}]", key, names)
    if not (isinstance(key, tuple) and not (len(key) == 2 and isinstance(key[1], int))):
        return test
    k = next(slots)
    return f"(args[{j}] is passed.get({k}) or ({test} and keep({k}, args[{j}])))"


def _no_match(args):
    return None


def match_on_first_call(kernel):
    """A stand-in for ``kernel.match`` that makes the matcher of ``kernel.compiled``
    at the kernel's first call and puts it in its place: a run calls a few dozen of the
    package's kernels, and making one costs tens of microseconds at import (its code
    stored by the build), milliseconds where it is compiled."""
    def first_match(args):
        kernel.match = matcher(kernel.compiled, stored_matcher_code(kernel.py_func,
                                                                   kernel.compiled))
        return kernel.match(args)
    return first_match


# the names a matcher's tests read besides its functions
_MATCH_NAMES = {"ndarray": np.ndarray,
                **{f"d_{name}": np.dtype(name) for name in _NUMBERS},
                **{f"s_{name}": frozenset(t for t, n in _SCALARS.items() if n == name)
                   for name in _NUMBERS}}


def _test(expr: str, key, names) -> str:
    """The Python expression that holds when ``_key(expr) == key``; an array or a tuple
    is bound to the next of ``names`` where it is first read."""
    if key is None:
        return "False"
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[1], int):  # an array
        dtype, ndim = key
        a = next(names)
        return (f"(type({a} := {expr}) is ndarray and ({a}.dtype is d_{dtype} or "
                f"{a}.dtype == d_{dtype}) and {a}.ndim == {ndim} and {a}.flags.carray)")
    if isinstance(key, tuple):
        t = next(names)
        items = [_test(f"{t}[{j}]", k, names) for j, k in enumerate(key)]
        return f"(type({t} := {expr}) is tuple and len({t}) == {len(key)} and " \
               f"{' and '.join(items) or 'True'})"
    return f"type({expr}) in s_{key}"


def store_matchers(folder: Path, kernels: dict) -> Path:
    """Write the compiled code of each kernel's matcher (``kernels``: (module, function)
    -> its argument keys in export order) to ``folder/MATCHERS``, marshalled after this
    interpreter's bytecode magic number, as a ``.pyc`` holds its code. Each matcher's
    code is marshalled on its own, to be read back only when its kernel is first called:
    reading all 71 took 1.0–1.7 ms, a run calls 12."""
    import importlib.util
    import marshal

    table = {name: (tuple(keys), marshal.dumps(matcher_code(tuple(keys))))
             for name, keys in kernels.items()}
    path = folder / MATCHERS
    path.write_bytes(importlib.util.MAGIC_NUMBER + marshal.dumps(table))
    return path


def _stored_matchers(folder: Path) -> dict:
    """The matchers' code ``store_matchers`` wrote in ``folder``; empty where there is
    none or it was written by another Python's bytecode."""
    import importlib.util
    import marshal

    try:
        data = (folder / MATCHERS).read_bytes()
        magic = importlib.util.MAGIC_NUMBER
        return marshal.loads(data[len(magic):]) if data.startswith(magic) else {}
    except (OSError, ValueError, EOFError, TypeError):
        return {}


def stored_matcher_code(py_func, entries: dict | None):
    """The stored code of this kernel's matcher if it tests ``entries``' keys in their
    order, else None (``matcher`` then compiles it)."""
    import marshal

    stored = _loaded.get("matchers", {}).get(_name(py_func))
    if stored is None or not entries or stored[0] != tuple(entries):
        return None
    try:
        return marshal.loads(stored[1])
    except (ValueError, EOFError, TypeError):
        return None


# ---- the table: "module.function(type, type, ...)", one line per compiled signature

def format_key(key) -> str:
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[1], int):
        dtype, ndim = key
        return f"{dtype}[{', '.join([':'] * (ndim - 1) + ['::1'])}]"
    if isinstance(key, tuple):
        inner = ", ".join(format_key(k) for k in key)
        return f"({inner},)" if len(key) == 1 else f"({inner})"
    return key


def parse_types(text: str) -> tuple:
    """``"float64[:, ::1], (int64[::1], bool), int64"`` -> the argument key."""
    import ast
    import re

    literal = re.sub(r"(\w+)\[([:, ]*)::1\]",
                     lambda m: f"('{m.group(1)}', {m.group(2).count(':') + 1})", text)
    literal = re.sub(r"(?<!['\w])([a-z]\w*)(?!['\w])", r"'\1'", literal)
    return tuple(ast.literal_eval(f"({literal},)"))


def key_to_json(key):
    """An argument key as JSON: [dtype, ndim] for an array, the name for a scalar,
    {"tuple": [...]} for a tuple (the manifest stores keys so: a start reads them
    without ``parse_types``, whose regular expressions cost milliseconds a start)."""
    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[1], int):
        return [key[0], key[1]]
    if isinstance(key, tuple):
        return {"tuple": [key_to_json(k) for k in key]}
    return key


def key_from_json(obj):
    """The argument key ``key_to_json`` wrote."""
    if isinstance(obj, list):
        return obj[0], obj[1]
    if isinstance(obj, dict):
        return tuple(key_from_json(k) for k in obj["tuple"])
    return obj


def read_table(path: Path = TABLE) -> list[tuple[str, str, tuple]]:
    """``[(module, function, argument key), ...]`` of the signature table."""
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            name, _, rest = line.partition("(")
            module, _, function = name.rpartition(".")
            rows.append((module, function, parse_types(rest[:-1])))
    return rows


# ---- the compiled module

def sources_digest() -> str:
    """SHA-256 of every kernel source (``ipcsim/kernels/**/*.py``) and the signature
    table, in path order."""
    h = hashlib.sha256()
    for path in sorted(KERNELS.rglob("*.py")) + [TABLE]:
        h.update(path.relative_to(HERE.parent).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def uname() -> tuple:
    """(system, node, release, version, machine): ``os.uname()`` where the system has it,
    as ``platform`` itself answers; that module (1.3 ms of every start to import) only
    where it has not."""
    if hasattr(os, "uname"):
        return tuple(os.uname())
    import platform

    return tuple(platform.uname())[:5]


def machine() -> str:
    """``platform.machine()``: x86_64, aarch64."""
    return uname()[4]


def cpu_features() -> list[str]:
    """This CPU's feature flags (Linux), sorted; empty where the system does not say."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith(("flags", "Features")):
                    return sorted(set(line.split(":", 1)[1].split()))
    except OSError:
        pass
    return []


def _installed_folders():
    """ipcsim/compiler folders holding a compiled module on the import path, other than
    this one: the installed ipcsim, while these sources run from a checkout."""
    for entry in sys.path:
        folder = Path(entry or ".").resolve() / "ipcsim" / "compiler"
        if folder != HERE and (folder / MANIFEST).is_file():
            yield folder


def _usable(folder: Path) -> dict | None:
    """The manifest in ``folder`` if its module fits these sources and this CPU."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if manifest.get("sources") != sources_digest() \
            or manifest.get("machine") != machine() \
            or not set(manifest.get("cpu_features", [])) <= set(cpu_features()):
        return None
    return manifest


def _load_module(folder: Path, manifest: dict):
    import importlib.util

    path = folder / manifest["module_file"]
    spec = importlib.util.spec_from_file_location(f"ipcsim.compiler.{MODULE_NAME}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_loaded = {}


def _entries() -> dict:
    """``{(module, function): {argument key: compiled function}}``, loaded once."""
    if "entries" not in _loaded:
        _loaded["entries"] = {}
        if os.environ.get("IPCSIM_AOT", "1").strip() != "0":
            for folder in (HERE, *_installed_folders()):
                manifest = _usable(folder)
                if manifest is not None:
                    module = _load_module(folder, manifest)
                    for mod, function, export, types, *json_key in manifest["exports"]:
                        key = (tuple(map(key_from_json, json_key[0])) if json_key
                               else parse_types(types))
                        _loaded["entries"].setdefault((mod, function), {})[key] = \
                            getattr(module, export)
                    _loaded["folder"] = folder
                    _loaded["matchers"] = _stored_matchers(folder)
                    break
    return _loaded["entries"]


def compiled_entry(py_func) -> dict | None:
    """The compiled variants of a kernel by argument key, or None where there are none."""
    return _entries().get(_name(py_func))


def _name(py_func) -> tuple[str, str]:
    """(module, function) of a kernel, as the table names it: the module's path under
    ``ipcsim.kernels`` (``contact.ccd``)."""
    return py_func.__module__.removeprefix("ipcsim.kernels."), py_func.__name__


def compiled_folder() -> Path | None:
    """Where the compiled kernels in use were found (None: numba compiles every kernel)."""
    _entries()
    return _loaded.get("folder")


# ---- calls that went to numba

_jit_kernels: set = set()  # the Python function of every kernel numba ran
_jit_calls: set | None = None  # (module, function, argument key), while recording


def note_jit_call(py_func, args) -> None:
    """Remember a kernel that ran without a compiled match (and, while recording, the
    argument types of the call)."""
    _jit_kernels.add(py_func)
    if _jit_calls is not None:
        _jit_calls.add((*_name(py_func), argument_types(args)))


def jit_kernels() -> list[str]:
    """The kernels this process ran through numba, sorted (``module.function``)."""
    return sorted(".".join(_name(f)) for f in _jit_kernels)


def start_recording() -> None:
    """From now on remember the argument types of every call that goes to numba."""
    global _jit_calls
    if _jit_calls is None:
        _jit_calls = set()


def recorded_calls() -> list[str]:
    """Each kernel call recorded since ``start_recording``, as a table line."""
    return sorted(f"{m}.{f}({', '.join(_format_or_unknown(k) for k in key)})"
                  for m, f, key in _jit_calls or ())


def _format_or_unknown(key) -> str:
    return "?" if key is None or (isinstance(key, tuple) and None in key) else format_key(key)
