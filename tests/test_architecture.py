"""The house's rules, checked by reading the code (imports and definitions, not running it):

* the package is layered (``LAYERS``): a module imports only from its own area and the
  layers below; no import cycle among its modules;
* only ``ipcsim/compiler/`` imports numba; kernels import nothing of ipcsim but the
  compiler and other kernels;
* the solver imports nothing of contact; the scene parser imports no numerics and nothing
  of the rest of ipcsim but ``errors``, ``atomic`` (the atomic writer), ``files`` (the
  reader that never blocks on a special file) and ``records``;
  ``scene/`` and ``io/`` do not lean on each other;
* the terms of the incremental potential are frozen records (msgspec Structs);
* Newton takes a problem, a start and a tolerance; no function takes more than eight
  parameters (numba kernels aside) or runs longer than about 80 lines.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
from pathlib import Path

import msgspec
import pytest

import ipcsim
import ipcsim.potentials

PACKAGE = Path(ipcsim.__file__).parent
MAX_PARAMETERS = 8
MAX_LINES = 85  # "about 80"


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path.relative_to(PACKAGE.parent), ast.parse(path.read_text(encoding="utf-8"))


def _imports(path: Path, tree: ast.Module) -> set[str]:
    """Absolute names of every module ``path`` imports (relative imports resolved)."""
    package = list(path.with_suffix("").parts[:-1])
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            found.add(module)
            found.update(f"{module}.{a.name}" for a in node.names)
    return found


def _area(path: Path) -> str:
    """``kernels``, ``solver``, ... for ipcsim/kernels/x.py; the module name at the top."""
    parts = path.with_suffix("").parts
    return parts[1] if len(parts) > 2 else parts[-1]


IMPORTS = {path: _imports(path, tree) for path, tree in _modules()}


def _offenders(rule) -> list[str]:
    return sorted(f"{path}: {name}" for path, names in IMPORTS.items()
                  for name in names if rule(path, name))


def _within(name: str, area: str) -> bool:
    return name == f"ipcsim.{area}" or name.startswith(f"ipcsim.{area}.")


def test_the_import_reader_sees_imports():
    assert "ipcsim.atomic.atomic_write_text" in IMPORTS[Path("ipcsim/scene/__init__.py")]
    assert "numba" in IMPORTS[Path("ipcsim/compiler/jit.py")]  # inside a function too


# Bottom to top: an area may import its own modules and those of the layers below it.
LAYERS = (
    ("compiler", "errors", "atomic", "records", "files", "__version__"),
    ("kernels", "start_up", "arguments"),
    ("scene",),
    ("model",),
    ("contact", "solver", "io"),
    ("potentials", "baselines"),
    ("simulation",),
    ("runner",),
    ("study",),
    ("commands",),
    ("cli", "__main__", "__init__"),
)
_LAYER = {area: i for i, areas in enumerate(LAYERS) for area in areas}


def test_every_area_has_a_layer():
    assert sorted({_area(p) for p in IMPORTS} - set(_LAYER)) == []


def test_imports_go_down_the_layers():
    def upwards(path, name):
        if not name.startswith("ipcsim."):
            return False
        target = name.split(".")[1]
        return target in _LAYER and _LAYER[target] > _LAYER[_area(path)]

    assert _offenders(upwards) == []


def _module_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (a name imported from a package's
    ``__init__`` counts as the submodule where there is one; a module's own packages,
    which Python runs first anyway, are left out)."""
    modules = {".".join(p.with_suffix("").parts).removesuffix(".__init__"): p
               for p in IMPORTS}
    graph = {}
    for module, path in modules.items():
        found = set()
        for name in IMPORTS[path]:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and not (module + ".").startswith(name + "."):
                found.add(name)
        graph[module] = found
    return graph


def test_no_import_cycle():
    """No module reaches itself through imports (lazy ones inside functions included)."""
    graph = _module_graph()
    cycles = []
    for start in graph:
        stack, seen = [(start, [start])], set()
        while stack:
            module, route = stack.pop()
            for nxt in graph[module]:
                if nxt == start:
                    cycles.append(" -> ".join(route + [nxt]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, route + [nxt]))
    assert cycles == []


def test_only_the_compiler_imports_numba():
    assert _offenders(lambda p, n: n.split(".")[0] == "numba" and _area(p) != "compiler") \
        == []


def test_kernels_import_nothing_of_ipcsim_but_kernels_and_the_compiler():
    assert _offenders(lambda p, n: _area(p) == "kernels" and n.startswith("ipcsim")
                      and not _within(n, "kernels") and not _within(n, "compiler")) == []


def test_the_solver_imports_nothing_of_contact():
    assert _offenders(lambda p, n: _area(p) == "solver" and _within(n, "contact")) == []


def test_the_scene_parser_imports_no_numerics():
    numerics = ("numpy", "scipy", "numba", "meshio")

    def bad(p, n):
        if _area(p) != "scene":
            return False
        if n.split(".")[0] in numerics:
            return True
        return n.startswith("ipcsim") and not any(
            _within(n, ok) for ok in ("scene", "errors", "atomic", "files", "records"))

    assert _offenders(bad) == []


@pytest.mark.parametrize("a, b", [("scene", "io"), ("io", "scene")])
def test_scene_and_io_do_not_import_each_other(a, b):
    assert _offenders(lambda p, n: _area(p) == a and _within(n, b)) == []


def _term_classes():
    for info in pkgutil.iter_modules(ipcsim.potentials.__path__):
        module = importlib.import_module(f"ipcsim.potentials.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and not getattr(cls, "_is_protocol", False) \
                    and all(
                    callable(getattr(cls, m, None)) for m in ("value", "gradient", "hessian")):
                yield cls


def test_terms_are_frozen_records():
    terms = list(_term_classes())
    assert len(terms) >= 8  # inertia, body force, elasticity, damping, contact, friction, ...
    for cls in terms:
        assert issubclass(cls, msgspec.Struct) and cls.__struct_config__.frozen, cls


def test_newton_takes_a_problem_a_start_and_a_tolerance():
    """... and, optionally, an iteration budget (an adaptive step's)."""
    from ipcsim.solver.newton import NewtonSolver

    parameters = inspect.signature(NewtonSolver.solve).parameters
    assert list(parameters) == ["self", "problem", "point", "tol", "max_iterations"]
    assert parameters["max_iterations"].default is None


def _functions():
    for path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path, node


def _is_kernel(node) -> bool:
    """A numba kernel: ``@njit(...)`` or ``@kernel(...)`` (compiler/twin.py)."""
    return any("jit" in ast.unparse(d) or ast.unparse(d).startswith("kernel(")
               for d in node.decorator_list)


def _parameters(node) -> int:
    a = node.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    count = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    return count - (names[:1] in (["self"], ["cls"]))


def test_no_function_takes_more_than_eight_parameters():
    assert [f"{p}:{n.lineno} {n.name}" for p, n in _functions()
            if not _is_kernel(n) and _parameters(n) > MAX_PARAMETERS] == []


def test_no_function_is_longer_than_about_80_lines():
    assert [f"{p}:{n.lineno} {n.name} ({n.end_lineno - n.lineno + 1} lines)"
            for p, n in _functions() if n.end_lineno - n.lineno + 1 > MAX_LINES] == []


def test_every_module_is_named_in_the_architecture():
    """docs/architecture.md names every module of the package (by its file name)."""
    text = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = [str(path.relative_to(PACKAGE)) for path in sorted(PACKAGE.rglob("*.py"))
               if path.name != "__init__.py" and f"`{path.name}`" not in text
               and f"{path.parent.name}/{path.name}" not in text]
    assert not missing, f"docs/architecture.md does not name {missing}"
