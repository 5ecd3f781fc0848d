"""Overrides: change a scene's values by dotted TOML key without editing its file.

``apply_overrides(spec, {"time.dt": 0.01, "shapes.0.material.E": 1e6})`` returns the
scene with exactly those values changed, read back through the TOML reader, so an
override is checked as the same value written in a TOML scene would be: an unknown key
or a bad value is a ``SceneError`` that names the key. It works for scenes of either
format: the scene is turned into its resolved TOML data (``scene_to_dict``, every value
and default written out), the values are set there, and the data is read and validated.

Keys are the TOML format's (docs/scene-format.md): ``table.key`` for the simple tables,
``shapes.N.key`` or ``shapes[N].key`` for the N-th shape (0-based, after a ``matrix`` is
expanded), likewise ``planes.N``, ``mesh_obstacles.N`` and ``shapes.N.dbc.M``. Aliases:
in a ``material`` table (the scene's or a shape's) ``E`` is ``youngs_modulus``, ``nu``
``poisson_ratio`` and ``rho`` ``density``. A shape without a material of its own gets a
copy of the scene's when one of its material values is set. Values are TOML values
(numbers, booleans, strings, arrays, inline tables); :func:`parse_assignment` reads
``KEY=VALUE`` as ``ipcsim run --set`` takes it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from msgspec.structs import replace

from ..errors import SceneError, excerpt
from .spec import SceneSpec
from .toml_reader import parse_toml_data
from .toml_writer import scene_to_dict

__all__ = ["apply_overrides", "parse_assignment", "normalise_key", "ALIASES"]

ALIASES = {"E": "youngs_modulus", "nu": "poisson_ratio", "rho": "density"}
_INDEXED = ("shapes", "planes", "mesh_obstacles", "dbc", "nbc")
_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _parts(key: str) -> list[str | int]:
    """``shapes.0.material.E`` or ``shapes[0].material.E`` -> ['shapes', 0, ...]."""
    if not isinstance(key, str) or not key.strip():
        raise ValueError("an empty key")
    key = key.strip()
    parts: list[str | int] = []
    pos = 0
    while pos < len(key):
        m = _PART.match(key, pos)
        if m is None:
            raise ValueError(f"'{excerpt(key)}' is not a dotted key")
        name, index = m.groups()
        if index is not None:
            parts.append(int(index))
        elif name.isdecimal():
            parts.append(int(name))
        else:
            parts.append(name.strip())
        pos = m.end()
        if pos < len(key) and key[pos] == ".":
            pos += 1
            if pos == len(key):
                raise ValueError(f"'{excerpt(key)}' ends with a dot")
    return parts


def _canonical(parts: list) -> list:
    """Aliases resolved: ``material.E`` -> ``material.youngs_modulus``."""
    out = list(parts)
    for i in range(1, len(out)):
        if out[i - 1] == "material" and out[i] in ALIASES:
            out[i] = ALIASES[out[i]]
    return out


def _written(parts: list) -> str:
    """The reader's name of a key path: ``shapes[0].material.youngs_modulus``."""
    text = ""
    for p in parts:
        text += f"[{p}]" if isinstance(p, int) else (f".{p}" if text else p)
    return text


def normalise_key(key: str) -> str:
    """The key as the TOML reader names it (aliases resolved, indices in brackets); a
    ``ValueError`` for text that is not a dotted key."""
    return _written(_canonical(_parts(key)))


def parse_assignment(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` -> (key, value): the value is read as a TOML value (``0.01``,
    ``true``, ``"NH"``, ``[0, 1, 0]``); a bare word that is no TOML value is taken as a
    string (``energy=FCR``). A ``ValueError`` without ``=`` or key."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"expected KEY=VALUE, got '{excerpt(text)}'")
    value = value.strip()
    import tomllib  # a run without --set reads no TOML value

    try:
        return key.strip(), tomllib.loads(f"v = {value}")["v"]
    except (tomllib.TOMLDecodeError, ValueError, RecursionError):
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-]*", value):
            return key.strip(), value
        raise ValueError(f"{key.strip()}: '{excerpt(value)}' is not a TOML value "
                         "(quote a string: KEY='\"text\"')") from None


def _set(doc: dict, parts: list, value, key: str, fail) -> None:
    """Set ``doc[parts...] = value``, making tables on the way."""
    node = doc
    for depth, part in enumerate(parts[:-1]):
        here = _written(parts[:depth + 1])
        nxt = parts[depth + 1]
        if isinstance(part, int):  # the entry was entered at the step before
            if depth == 0:
                fail(f"an index must follow an array name ({', '.join(_INDEXED)})")
            continue
        child = node.get(part) if isinstance(node, dict) else None
        if isinstance(nxt, int):
            if not isinstance(child, list):
                fail(f"{here} is not an array of tables, so it has no entry {nxt}")
            if nxt >= len(child):
                n = len(child)
                fail(f"the scene has {n} {here} entr{'y' if n == 1 else 'ies'} (index 0 to "
                     f"{n - 1}), so no {here}[{nxt}]" if n else f"the scene has no {here}")
            node = child[nxt]
            continue
        if child is None and isinstance(node, dict):
            child = node[part] = {}
        if not isinstance(child, dict):
            fail(f"{here} is a value, not a table, so it has no key '{nxt}'")
        node = child
    last = parts[-1]
    if isinstance(last, int) or not isinstance(node, dict):
        fail("an override sets a value by name, not an entry of an array")
    node[last] = value


def _document(spec: SceneSpec) -> dict:
    """The scene as TOML data with absolute paths, as the reader takes it back."""
    doc = scene_to_dict(spec, spec.source.parent if spec.source else None,
                        name_path=lambda p: str(p))
    if spec.dhat_start is None:  # "no homotopy" follows a changed dhat
        doc["contact"].pop("dhat_start", None)
    return doc


def _fill_material(doc: dict, parts: list) -> None:
    """A shape whose material is set gets a copy of the scene's first."""
    if len(parts) > 3 and parts[0] == "shapes" and isinstance(parts[1], int) \
            and parts[2] == "material":
        shapes = doc.get("shapes", [])
        if 0 <= parts[1] < len(shapes) and "material" not in shapes[parts[1]]:
            m = doc["material"]
            shapes[parts[1]]["material"] = {k: m[k] for k in ("density", "youngs_modulus",
                                                              "poisson_ratio")}


def apply_overrides(spec: SceneSpec, overrides: Mapping[str, object] | None) -> SceneSpec:
    """``spec`` with the values of ``overrides`` (dotted TOML key -> value) set, read and
    validated as a TOML scene; ``SceneError`` naming the key for an unknown key or a
    bad value. The result records the overrides (``spec.overrides``)."""
    if not overrides:
        return spec
    source = spec.source
    doc = _document(spec)
    keys: dict[str, str] = {}  # as given -> as the reader names it
    for key, value in overrides.items():
        try:
            parts = _canonical(_parts(key))
        except ValueError as exc:
            raise SceneError(source, None, f"override '{excerpt(key)}': {exc}") from None
        keys[key] = _written(parts)

        def fail(message, key=key):
            raise SceneError(source, None, f"override {excerpt(key, 80)}: {message}")

        _fill_material(doc, parts)
        _set(doc, parts, value, key, fail)
    try:
        new = parse_toml_data(doc, source)
    except SceneError as exc:
        raise _name_the_key(exc, keys, overrides, source) from None
    return _with_provenance(new, spec, keys, overrides)


def _name_the_key(exc: SceneError, keys: dict, overrides: Mapping, source) -> SceneError:
    """The reader's error, said of the override that caused it (or of all of them)."""
    def names(written: str) -> bool:
        if written in exc.message:
            return True
        prefixes = [written[:m.start()] for m in re.finditer(r"[.\[]", written)]
        return any(re.search(rf"unknown key {re.escape(p)}(?![\w.\[])", exc.message)
                   for p in prefixes)

    named = [k for k, w in keys.items() if names(w)]
    if len(named) == 1:
        key = named[0]
        prefix = f"override {excerpt(key, 80)} = {excerpt(repr(overrides[key]))}"
    else:
        prefix = "with the overrides " + ", ".join(excerpt(k, 80) for k in keys)
    return SceneError(source, None, f"{prefix}: {exc.message}")


def _with_provenance(new: SceneSpec, old: SceneSpec, keys: dict, overrides) -> SceneSpec:
    """Lines, paths as written and warnings of the file, where overrides left them."""
    changed = set(keys.values())
    lines = {k: v for k, v in old.key_lines.items()
             if not any(k == c or k.startswith(c + ".") for c in changed)}
    def kept(items, before, *names):
        if len(items) != len(before):
            return items
        return tuple(replace(s, **{n: getattr(o, n) for n in names})
                     for s, o in zip(items, before))

    shapes = kept(new.shapes, old.shapes, "path", "line")
    seen = {w.partition("warning: ")[2] for w in old.warnings}
    more = tuple(w for w in new.warnings if w.partition("warning: ")[2] not in seen)
    return replace(new, shapes=shapes, planes=kept(new.planes, old.planes, "line"),
                   mesh_obstacles=kept(new.mesh_obstacles, old.mesh_obstacles,
                                       "path", "line"),
                   source=old.source, key_lines=lines,
                   warnings=old.warnings + more, ignored=old.ignored,
                   overrides={**old.overrides, **overrides})
