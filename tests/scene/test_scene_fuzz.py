"""Mutated scripts give a SceneError or a scene, never another exception."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scene_support import example_scripts

from ipcsim.errors import SceneError
from ipcsim.scene import parse_txt
from ipcsim.scene.spec import SceneSpec

JUNK = ["abc", "nan", "inf", "-inf", "1e999", "#", "\\", "-1", "0", "1e-300", "99999999",
        "1.5", "DBC", "material", "section", "end", "tol", "tuning", "shapes", "input", ".5e",
        "meshes/cube.msh", "meshes/tri.obj"]


@pytest.fixture(scope="module")
def corpus(rich_scene_module):
    """(path, text) of the rich synthetic scene and of every example script present."""
    paths = [rich_scene_module, *example_scripts()]
    return [(p, p.read_text()) for p in paths]


# one mutation: (kind, line pick, token pick, second token pick, junk pick)
MUTATION = st.tuples(st.sampled_from(["delete", "duplicate", "swap", "junk", "truncate",
                                      "copy line", "drop line"]),
                     st.integers(0, 10**6), st.integers(0, 10**6), st.integers(0, 10**6),
                     st.sampled_from(JUNK))


def mutate(text: str, mutations) -> str:
    rows = [line.split() for line in text.split("\n")]
    for kind, li, a, b, junk in mutations:
        row = rows[li % len(rows)]
        if kind == "delete" and row:
            del row[a % len(row)]
        elif kind == "duplicate" and row:
            row.insert(a % len(row), row[a % len(row)])
        elif kind == "swap" and row:
            i, j = a % len(row), b % len(row)
            row[i], row[j] = row[j], row[i]
        elif kind == "junk" and row:
            row[a % len(row)] = junk
        elif kind == "truncate":
            del row[a % (len(row) + 1):]
        elif kind == "copy line":
            rows.insert(li % len(rows), list(rows[a % len(rows)]))
        elif kind == "drop line" and len(rows) > 1:
            del rows[li % len(rows)]
    return "\n".join(" ".join(r) for r in rows)


@settings(max_examples=100, deadline=None)
@given(pick=st.integers(0, 10**6), mutations=st.lists(MUTATION, min_size=1, max_size=4))
def test_mutated_scripts_fail_only_with_scene_errors(corpus, pick, mutations):
    path, text = corpus[pick % len(corpus)]
    try:
        spec = parse_txt(mutate(text, mutations), path)
    except SceneError as err:
        assert str(err).startswith(str(path))
        assert err.line is None or err.line >= 1
    else:
        assert isinstance(spec, SceneSpec) and spec.shapes
