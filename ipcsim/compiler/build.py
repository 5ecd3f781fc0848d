"""Build the compiled kernels of ``aot.py``.

    python -m ipcsim.compiler.build OUT_FOLDER

compiles the serial variant of every (kernel, argument types) of signatures.txt into
OUT_FOLDER/_compiled*.so with numba's ahead-of-time compiler (numba.pycc), and writes
OUT_FOLDER/_compiled.json and the compiled code of each kernel's argument matcher,
OUT_FOLDER/_compiled.matchers; setup.py runs it when ipcsim is installed.
(``tools/kernel_signatures.py`` writes signatures.txt from the calls scenes make.)

Each export is a one-line function that calls the kernel's numba dispatcher, so the kernel
is compiled with its own options (``error_model``, ``inline``) as under the JIT; numba's
cache is pointed at an empty folder, since a library loaded from the cache cannot be linked
into the module. The module is built for this CPU where its features can be read
(``aot.cpu_features``), and for a generic one of its architecture where not.

A build is kept in a cache (``$IPCSIM_BUILD_CACHE``, else ``$XDG_CACHE_HOME/ipcsim`` or
``~/.cache/ipcsim``) under a key of everything its code depends on: the sources digest,
numba's and numpy's versions, the Python ABI, the machine and the CPU features it was built
for. Installing unchanged kernels again (``pip install .`` then ``pip install ".[test]"``,
or a reinstall) copies the cached build instead of compiling for minutes.
``--no-cache`` builds afresh.

This is the one module that imports ``numba.pycc`` (``numba_can_compile_ahead``), which
numba's documentation marks as pending deprecation: where it is gone, the install goes on
without a compiled module, numba compiles every kernel on first use, and the test
``tests/compiler/test_install.py`` fails so that it is not missed.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import importlib.metadata
import json
import os
import shutil
import sys
import sysconfig
import tempfile
import time
import warnings
from pathlib import Path

from . import aot


def _numba_type(key):
    from numba.core import types

    if isinstance(key, tuple) and len(key) == 2 and isinstance(key[1], int):
        return types.Array(getattr(types, key[0]), key[1], "C")
    if isinstance(key, tuple):
        return types.Tuple([_numba_type(k) for k in key])
    return types.boolean if key == "bool" else getattr(types, key)


def _trampoline(dispatcher, n_args: int):
    """``def call(a0, ..., aN): return kernel(a0, ..., aN)`` calling ``dispatcher``."""
    args = ", ".join(f"a{i}" for i in range(n_args))
    namespace = {"kernel": dispatcher}
    exec(f"def call({args}):\n    return kernel({args})\n", namespace)  # noqa: S102
    return namespace["call"]


def _dispatcher(module: str, function: str):
    from .twin import Kernel

    kernel = getattr(importlib.import_module(f"ipcsim.kernels.{module}"), function)
    return kernel.variant(False) if isinstance(kernel, Kernel) else kernel.dispatcher()


def build(out_folder: Path, verbose: bool = False) -> Path:
    """Compile the table's kernels into ``out_folder``; returns the manifest's path."""
    os.environ["IPCSIM_AOT"] = "0"  # this process compiles; it must not use a compiled module
    with tempfile.TemporaryDirectory() as cache:
        os.environ["NUMBA_CACHE_DIR"] = cache
        from .jit import numba_module

        numba_module()
        from numba.pycc import CC

        out_folder.mkdir(parents=True, exist_ok=True)
        cc = CC(aot.MODULE_NAME)
        cc.output_dir = str(out_folder)
        cc.target_cpu = "host" if aot.cpu_features() else ""
        cc.verbose = verbose
        exports = []
        kernels = {}  # (module, function) -> its argument keys, in export order
        for i, (module, function, key) in enumerate(aot.read_table()):
            dispatcher = _dispatcher(module, function)
            argtypes = tuple(_numba_type(k) for k in key)
            dispatcher.compile(argtypes)
            export = f"{module.replace('.', '_')}__{function}__{i}"
            cc.export(export, dispatcher.overloads[argtypes].signature)(
                _trampoline(dispatcher, len(key)))
            exports.append([module, function, export,
                            ", ".join(aot.format_key(k) for k in key),
                            [aot.key_to_json(k) for k in key]])
            kernels.setdefault((module, function), []).append(key)
        cc.compile()
    aot.store_matchers(out_folder, kernels)
    manifest = {"sources": aot.sources_digest(), "machine": aot.machine(),
                "cpu_features": aot.cpu_features() if cc.target_cpu else [],
                "numba": numba_module().__version__, "module_file": cc.output_file,
                "exports": exports}
    path = out_folder / aot.MANIFEST
    path.write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
    return path


def c_compiler() -> str | None:
    """The C compiler numba's ahead-of-time compiler would call, None if there is none."""
    name = (os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0]
    return shutil.which(name)


def numba_can_compile_ahead() -> str | None:
    """None where numba's ahead-of-time compiler can be used here, else why not."""
    try:
        with warnings.catch_warnings():  # its pending deprecation is why this is asked
            warnings.simplefilter("ignore")
            from numba.pycc import CC  # noqa: F401
    except ImportError as exc:
        return f"numba {_version('numba')} has no ahead-of-time compiler ({exc})"
    if c_compiler() is None:
        return "there is no C compiler on PATH"
    return None


def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


# ---- the build cache

FILES = (aot.MANIFEST, aot.MATCHERS)  # beside the module file the manifest names


def cache_root() -> Path:
    """Where builds are kept (module docstring)."""
    if os.environ.get("IPCSIM_BUILD_CACHE"):
        return Path(os.environ["IPCSIM_BUILD_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "ipcsim"


def build_key() -> str:
    """The digest of what a build's code depends on: equal keys, the same module."""
    what = {"sources": aot.sources_digest(), "numba": _version("numba"),
            "numpy": _version("numpy"), "python": sysconfig.get_config_var("EXT_SUFFIX"),
            "machine": aot.machine(), "cpu_features": aot.cpu_features()}
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()[:32]


def _build_files(folder: Path) -> list[Path] | None:
    """The files of the build in ``folder`` (manifest first), None if it holds none."""
    try:
        manifest = json.loads((folder / aot.MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    files = [folder / name for name in (*FILES, manifest.get("module_file", ""))]
    return files if all(f.is_file() for f in files) else None


def from_cache(out_folder: Path, root: Path) -> Path | None:
    """Copy the cached build for these sources into ``out_folder``; its manifest's path,
    or None where the cache has none."""
    files = _build_files(root / "compiled" / build_key())
    if files is None:
        return None
    out_folder.mkdir(parents=True, exist_ok=True)
    for f in reversed(files):  # the manifest last: a copy cut short is no build
        shutil.copyfile(f, out_folder / f.name)
    return out_folder / aot.MANIFEST


def into_cache(out_folder: Path, root: Path) -> None:
    """Keep the build in ``out_folder`` in the cache (all its files appear at once)."""
    files = _build_files(out_folder)
    target = root / "compiled" / build_key()
    if files is None or target.exists():
        return
    staging = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=target.parent, prefix=".staging-"))
        for f in files:
            shutil.copyfile(f, staging / f.name)
        os.replace(staging, target)
    except OSError as exc:  # a cache that cannot be written costs the next install time only
        print(f"ipcsim: the build is not cached ({exc})", file=sys.stderr)
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ipcsim.compiler.build")
    parser.add_argument("out_folder", type=Path)
    parser.add_argument("-v", "--verbose", action="store_true")
    parser.add_argument("--no-cache", action="store_true",
                        help="compile afresh, neither reading nor writing the build cache")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    root = None if args.no_cache else cache_root()
    path = from_cache(args.out_folder, root) if root else None
    if path is not None:
        print(f"compiled kernels -> {path.parent} (from the build cache {root})")
        return 0
    why_not = numba_can_compile_ahead()
    if why_not is not None:
        print(f"ipcsim: cannot compile the kernels ahead of time: {why_not}", file=sys.stderr)
        return 1
    path = build(args.out_folder, args.verbose)
    if root is not None:
        into_cache(args.out_folder, root)
    print(f"compiled kernels -> {path.parent} ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
