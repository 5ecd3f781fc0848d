"""Fuzzing the scene readers: mutated example scenes (token swaps, deletions, numeric edge
values, junk words, random bytes; for TOML also values of every wrong type) give a
SceneSpec or a SceneError (one line, naming the file), never another exception.

Each mutated scene is read as if it were the file it came from (its bytes through the
same decoding as a file's), so the examples' mesh paths resolve. The examples are drawn
from a fixed seed (``derandomize``), so a failure reproduces. CI runs a bounded number per
test; ``IPCSIM_FUZZ_EXAMPLES=10000 python -m pytest tests/scene/test_scene_fuzz.py`` runs
more. Time per case is bounded by the size of the inputs (a few KB each), not asserted.
"""

from __future__ import annotations

import copy
import os
import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scene_support import RICH_2D_SCENE, example_scripts

from ipcsim.errors import SceneError
from ipcsim.scene import format_toml, load_scene, parse_toml, parse_txt, scene_text
from ipcsim.scene.spec import SceneSpec

EXAMPLES = int(os.environ.get("IPCSIM_FUZZ_EXAMPLES", "150"))
FUZZ = settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# numbers at the edges of what a reader must take or refuse, and words that are not numbers
EDGE = ["0", "-0", "1", "-1", "0.5", ".5", "5.", "1e308", "-1e308", "1e309", "1e-320", "inf",
        "-inf", "nan", "NaN", "infinity", "9" * 30, "1" * 5000, "0x10", "1_000", "1e", "+", "-",
        ".", "\u0661", "\u00bd", "1,5", "2147483648", "-9223372036854775809", "1e20"]
JUNK = ["abc", "#", "\\", "DBC", "NBC", "material", "section", "end", "tol", "tuning",
        "shapes", "shape", "input", "meshes/cube.msh", "meshes/tri.obj", "time", "ground",
        "IP", "QP", "section end", "../", "/dev/zero", "\u00e9", "\u202e", "\t", "x" * 300]
LINES = ["time 1e300 1e-300", "fricIterAmt 100000000000000000000", "density 1e300",
         "shapes input 1", "shapes input 100", "tol 3", "tuning 9", "section QP",
         "shapeMatrix input 1000 1000 1000", "script twist 1 2", "restart status42",
         "meshCO meshes/plane.obj 0 0 0 0 0 0", "appendStr a/b", "playBackSpeed -1"]

TXT_MUTATION = st.tuples(
    st.sampled_from(["delete", "duplicate", "swap", "swap lines", "edge", "junk", "truncate",
                     "copy line", "drop line", "add line", "bytes"]),
    st.integers(0, 10**6), st.integers(0, 10**6), st.integers(0, 10**6),
    st.sampled_from(EDGE + JUNK + LINES), st.binary(min_size=1, max_size=8))


def mutate_txt(text: str, mutations) -> bytes:
    rows = [line.split() for line in text.split("\n")]
    raw: list[tuple[int, bytes]] = []
    for kind, li, a, b, word, junk in mutations:
        row = rows[li % len(rows)]
        if kind in ("delete", "duplicate", "swap", "edge", "junk") and not row:
            continue
        if kind == "delete":
            del row[a % len(row)]
        elif kind == "duplicate":
            row.insert(a % len(row), row[a % len(row)])
        elif kind == "swap":
            i, j = a % len(row), b % len(row)
            row[i], row[j] = row[j], row[i]
        elif kind in ("edge", "junk"):
            row[a % len(row)] = word
        elif kind == "swap lines":
            i, j = li % len(rows), a % len(rows)
            rows[i], rows[j] = rows[j], rows[i]
        elif kind == "truncate":
            del row[a % (len(row) + 1):]
        elif kind == "copy line":
            rows.insert(li % len(rows), list(rows[a % len(rows)]))
        elif kind == "drop line" and len(rows) > 1:
            del rows[li % len(rows)]
        elif kind == "add line":
            rows.insert(li % (len(rows) + 1), word.split())
        elif kind == "bytes":
            raw.append((a, junk))
    data = "\n".join(" ".join(r) for r in rows).encode("utf-8")
    for pos, junk in raw:  # random bytes at random places (may break UTF-8)
        pos %= len(data) + 1
        data = data[:pos] + junk + data[pos:]
    return data


# values of every type for a TOML key, and what to do with it
TOML_VALUES = st.one_of(
    st.sampled_from([0, -1, 1, 2**63 - 1, -(2**63), 10**20, 0.0, -0.0, 1e308, 1e-320,
                     float("inf"), float("-inf"), float("nan"), True, False, "", "adaptive",
                     "NH", "BE", "ground", "halfSpace", "meshes/cube.msh", "x" * 300,
                     "/dev/zero", [], [0], [1.0, 2.0], [1.0, 2.0, 3.0], [1, 2, 3, 4],
                     ["a", "b", "c"], [[1.0, 2.0, 3.0]], {}, {"a": 1}, [{}], [{"path": 1}]]),
    st.text(max_size=20), st.floats(), st.integers(-(2**64), 2**64))
TOML_MUTATION = st.tuples(st.sampled_from(["set", "delete", "add", "wrap"]),
                          st.integers(0, 10**6), TOML_VALUES,
                          st.sampled_from(["path", "kind", "dt", "foo", "dbc", "nbc",
                                           "matrix", "counts", "normal", "friction",
                                           "dimension", "size", "resolution", "velocity",
                                           "limit", "rotation_deg", "spring_stiffness"]))


def _places(doc, out, depth=0):
    """Every (container, key) pair of a TOML document, tables and arrays alike."""
    if depth > 6:
        return out
    items = doc.items() if isinstance(doc, dict) else enumerate(doc)
    for key, value in items:
        out.append((doc, key))
        if isinstance(value, (dict, list)):
            _places(value, out, depth + 1)
    return out


def mutate_toml(doc: dict, mutations) -> dict:
    for kind, pick, value, name in mutations:
        value = copy.deepcopy(value)  # sampled values are shared between examples
        places = _places(doc, [])
        if not places:
            break
        container, key = places[pick % len(places)]
        if kind == "set":
            container[key] = value
        elif kind == "delete" and isinstance(container, dict):
            del container[key]
        elif kind == "add" and isinstance(container, dict):
            container[name] = value
        elif kind == "wrap":
            container[key] = [container[key]]
    return doc


@pytest.fixture(scope="module")
def txt_corpus(rich_scene_module):
    """(path, text) of the rich synthetic scene and of every example script present."""
    paths = [rich_scene_module, *example_scripts()]
    return [(p, p.read_text()) for p in paths]


@pytest.fixture(scope="module")
def toml_corpus(rich_scene_module, tmp_path_factory):
    """The same scenes as TOML (written into the rich scene's folder, so that the mesh
    paths of both resolve), and the rich 2D scene, as (path, parsed document)."""
    out = []
    rich_2d = rich_scene_module.parent / "rich_2d.toml"
    rich_2d.write_text(RICH_2D_SCENE)
    for k, source in enumerate([rich_scene_module, rich_2d, *example_scripts()]):
        path = rich_scene_module.parent / f"fuzz_{k}.toml"
        path.write_text(format_toml(load_scene(source), path))
        out.append((path, tomllib.loads(path.read_text())))
    return out


def read_or_refuse(data: bytes, path: Path) -> None:
    """The scene read from ``data`` as if it were the file ``path`` (so the examples' mesh
    paths resolve where they are) is a SceneSpec, or a SceneError that is one short line
    naming the file; anything else fails the test."""
    parse = parse_toml if path.suffix == ".toml" else parse_txt
    try:
        spec = parse(scene_text(data, path), path)
    except SceneError as err:
        text = str(err)
        assert text.startswith(str(path)), text
        assert "\n" not in text and len(text) < 1000, text
        assert err.line is None or err.line >= 1
    else:
        assert isinstance(spec, SceneSpec) and spec.shapes
        assert all(len(w) < 1000 for w in spec.warnings)


@FUZZ
@given(pick=st.integers(0, 10**6), mutations=st.lists(TXT_MUTATION, min_size=1, max_size=5))
def test_mutated_scripts_fail_only_with_scene_errors(txt_corpus, pick, mutations):
    source, text = txt_corpus[pick % len(txt_corpus)]
    read_or_refuse(mutate_txt(text, mutations), source)


@FUZZ
@given(pick=st.integers(0, 10**6), mutations=st.lists(TOML_MUTATION, min_size=1, max_size=4))
def test_mutated_toml_documents_fail_only_with_scene_errors(toml_corpus, pick, mutations):
    source, doc = toml_corpus[pick % len(toml_corpus)]
    try:
        text = tomli_w.dumps(mutate_toml(copy.deepcopy(doc), mutations))
    except (TypeError, ValueError):  # a document TOML cannot hold (None, a key of 1)
        return
    read_or_refuse(text.encode(), source)


@FUZZ
@given(pick=st.integers(0, 10**6), mutations=st.lists(TXT_MUTATION, min_size=1, max_size=5))
def test_mutated_toml_text_fails_only_with_scene_errors(toml_corpus, pick, mutations):
    source, _ = toml_corpus[pick % len(toml_corpus)]
    read_or_refuse(mutate_txt(source.read_text(), mutations), source)
