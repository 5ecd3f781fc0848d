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
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import tempfile
import time
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ipcsim.compiler.build")
    parser.add_argument("out_folder", type=Path)
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    path = build(args.out_folder, args.verbose)
    print(f"compiled kernels -> {path.parent} ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
