"""Installing ipcsim compiles its kernels ahead of time (ipcsim/compiler/aot.py).

Everything else about the package is in pyproject.toml. The compiled kernels are one
extension module, built by ``python -m ipcsim.compiler.build`` (numba's ahead-of-time
compiler) from the sources being installed. It is optional: where it cannot be built, the
install goes on and numba compiles each kernel on its first use instead. A build is
cached (``build.py``), so installing the same kernels again copies it instead of
compiling. Set ``IPCSIM_AOT=0`` to install without it.
"""

import os
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
COMPILED = "ipcsim.compiler._compiled"
COMPANIONS = ("_compiled.json", "_compiled.matchers")  # its manifest, its matchers' code


class BuildKernels(build_ext):
    """build_ext for the compiled kernels: runs compiler/build.py into the extension's folder."""

    def build_extension(self, ext):
        if ext.name != COMPILED:
            return super().build_extension(ext)
        if os.environ.get("IPCSIM_AOT", "1").strip() == "0":
            print("ipcsim: IPCSIM_AOT=0, kernels not compiled ahead of time")
            return None
        folder = Path(self.get_ext_fullpath(ext.name)).parent
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
        print(f"ipcsim: compiling kernels ahead of time into {folder} (a few minutes)")
        done = subprocess.run([sys.executable, "-m", "ipcsim.compiler.build", str(folder)],
                              cwd=ROOT, env=env)
        if done.returncode != 0:
            print("ipcsim: WARNING: the kernels could not be compiled ahead of time; "
                  "numba will compile each on its first use", file=sys.stderr)
        return None

    def get_outputs(self):
        # only what was built (the compiled kernels are optional), with its companions
        built = [path for path in super().get_outputs() if os.path.exists(path)]
        return built + [str(Path(path).with_name(name)) for path in built
                        for name in COMPANIONS if Path(path).with_name(name).exists()]

    def copy_extensions_to_source(self):
        # an editable install: the companions go into the sources with the module
        super().copy_extensions_to_source()
        build_py = self.get_finalized_command("build_py")
        for ext in self.extensions:
            if ext.name == COMPILED:
                inplace, regular = self._get_inplace_equivalent(build_py, ext)
                for name in COMPANIONS:
                    if Path(regular).with_name(name).exists():
                        self.copy_file(str(Path(regular).with_name(name)),
                                       str(Path(inplace).with_name(name)))


setup(ext_modules=[Extension(COMPILED, sources=[], optional=True)],
      cmdclass={"build_ext": BuildKernels})
