"""The original IPC program's scene scripts (``.txt`` / ``.ipc``): the reader.

The format (docs/scene-format.md has the user's reference):

* read line by line; the first whitespace-separated token is the keyword, the rest its
  arguments; a token starting with ``#`` comments out the rest of the line;
* a later occurrence of a keyword overwrites an earlier one, except ``shapes``, ``shape``,
  ``shapeMatrix``, ``ground``, ``halfSpace`` and ``meshCO``, which append;
* ``tol N`` and ``tuning N`` read N numbers from the *following* lines;
* ``shapes <word> N`` reads the next N non-blank, non-comment lines as shape lines, where
  a ``\\`` token continues the line on the next physical line (also inside a comment);
* ``section <solver> ...`` blocks are parsed only when they name the solver selected so
  far (``constraintSolver`` before the block, interiorPoint by default), else skipped up to
  ``section end``, as the original does.

Where the original silently does something surprising (a non-numeric token read as 0,
values on the ``tol`` line ignored, unknown keywords skipped) this reader raises a
``SceneError`` naming the file and line instead.
"""

from __future__ import annotations

import bisect
import math
import re
import sys
from pathlib import Path

from msgspec.structs import replace

from ..errors import SceneError, excerpt as _q
from . import paths
from .spec import (CONSTRAINT_TYPES, UNSUPPORTED_CONSTRAINT_TYPES, ENERGIES, INF,
                   INTEGRATORS, MESH_KINDS, SUPPORTED_SCRIPTS, DirichletSpec,
                   InitialVelocitySpec, MaterialSpec, MeshObstacleSpec, NeumannSpec,
                   PlaneSpec, SceneSpec, ShapeSpec)
from .validate import LINEAR_SOLVERS, validate_scene

__all__ = ['parse_txt', 'KEYWORDS', 'USAGE', 'suggest', 'unit_normal']

# A number as C++ stream extraction reads it, plus inf/nan so that we can name the problem.
# ASCII digits only: Python's float() and int() also read other scripts' digits (١).
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)\Z",
                     re.IGNORECASE | re.ASCII)
_INTEGER = re.compile(r"[+-]?\d{1,18}\Z", re.ASCII)  # a count: int64, no huge texts
_DIGITS = re.compile(r"[+-]?\d+\Z", re.ASCII)
# Finding the lines with content: comments removed, the next character that is not
# whitespace starts one (runs of blank and comment lines cost one search).
_NON_SPACE = re.compile(r"\S")
_FROM_HASH = re.compile(r"#[^\n]*")

# tuning = [kappa (0: adaptive), dHat start, dHat target, dTol, eps_v start, eps_v target];
# the optimizer's built-in values fill the entries a short `tuning N` leaves out.
_TUNING_DEFAULTS = (0.0, 1e-3, 1e-3, 1e-9, 1e-3, 1e-3)
_TUNING_KEYS = ("contact.kappa", "contact.dhat_start", "contact.dhat", "contact.dtol",
                "contact.epsv", "contact.epsv")

# A shapeMatrix can multiply a mesh; beyond this the scene is surely a typo.
_MAX_MATRIX_COPIES = 100_000

SOLVER_NAMES = {"interiorPoint": "interiorPoint", "IP": "interiorPoint", "SQP": "SQP",
                "QP": "QP"}

USAGE = {
    "shapes": "shapes input <N>, then N shape lines",
    "shape": "shape input <mesh>",
    "shapeMatrix": "shapeMatrix input <nx> <ny> <nz> [<px> <py> <pz>], then one line "
                   "<mesh> <dx> <dy> <dz> <rx> <ry> <rz> <sx> <sy> <sz> [material <rho> <E> <nu>]",
    "ground": "ground <friction> <height>",
    "halfSpace": "halfSpace <ox> <oy> <oz> <nx> <ny> <nz> <stiffness> <friction>",
    "meshCO": "meshCO <mesh.obj> <ox> <oy> <oz> <size> <stiffness> <friction> "
              "[rotate <rx> <ry> <rz>]",
    "time": "time <duration> [<dt>]",
    "density": "density <rho>",
    "stiffness": "stiffness <E> <nu>",
    "energy": "energy NH|FCR",
    "timeIntegration": "timeIntegration BE | timeIntegration NM [<beta> [<gamma>]] | "
                       "timeIntegration BDF2",
    "timeTolerance": "timeTolerance <relative error>",
    "turnOffGravity": "turnOffGravity",
    "dampingStiff": "dampingStiff <k>",
    "dampingRatio": "dampingRatio <r>",
    "selfCollisionOn": "selfCollisionOn",
    "selfCollisionOff": "selfCollisionOff",
    "selfFric": "selfFric <mu>",
    "dHat": "dHat <relative distance>",
    "epsv": "epsv <relative velocity>",
    "dHatAbs": "dHatAbs <metres>",
    "epsvAbs": "epsvAbs <m/s>",
    "kappa": "kappa <barrier stiffness>",
    "fricIterAmt": "fricIterAmt <n>",
    "tol": "tol <N>, then N numbers on the following lines",
    "tuning": "tuning <N>, then N numbers on the following lines",
    "kappaMinMultiplier": "kappaMinMultiplier <c>",
    "minBarrierStiffnessScale": "minBarrierStiffnessScale <c>",
    "useAbsParameters": "useAbsParameters",
    "DBCTimeRange": "DBCTimeRange <t0> [<t1>]",
    "NBCTimeRange": "NBCTimeRange <t0> [<t1>]",
    "warmStart": "warmStart <0..5>",
    "constraintSolver": "constraintSolver interiorPoint|IP|SQP|QP",
    "constraintType": "constraintType volume|graphics|gapFunction|Verschoor",
    "constraintOffset": "constraintOffset <c>",
    "useActiveSetConvergence": "useActiveSetConvergence",
    "noActiveSetConvergence": "noActiveSetConvergence",
    "section": "section <solver> [<solver> ...] ... section end",
    "size": "size <s>",
    "rotateModel": "rotateModel <ax> <ay> <az> <degrees>",
    "handleRatio": "handleRatio <r>",
    "restart": "restart <status file>",
    "script": "script <name> [<N> <p1> ... <pN>]",
    "linearSolver": "linearSolver CHOLMOD|EIGEN|AMGCL|scipy|auto",
    "linSysSolver": "linSysSolver CHOLMOD|EIGEN|AMGCL|scipy|auto",
    "appendStr": "appendStr <word>",
    "playBackSpeed": "playBackSpeed <s>",
}
SHAPE_USAGE = ("<mesh> <tx> <ty> <tz> <rx> <ry> <rz> <sx> <sy> <sz> [material ...] "
               "[linearVelocity ...] [angularVelocity ...] [DBC ...] [NBC ...] [initVel ...] "
               "[meshSeq <folder>]")
SHAPE_EXTRAS = ("material", "linearVelocity", "angularVelocity", "DBC", "NBC", "initVel",
                "meshSeq")

# Accepted, recorded in SceneSpec.ignored, no effect: viewer-only, QP/SQP-only, and the
# CCD choice (ipcsim has its own continuous collision detection).
IGNORED_KEYWORDS = ("view", "zoom", "cameraTracking", "disableCout", "QPSolver",
                    "CCDMethod", "ccdMethod", "CCDTolerance", "ccdTolerance")
# Keywords found in the original's own scripts that the original does not know either.
NOOP_KEYWORDS = ("timeStepper", "inexactSolve", "resolution")


def suggest(word: str, choices) -> str:
    """`` (did you mean 'x'?)`` for the closest choice, compared case-insensitively."""
    if len(word) > 60:  # no keyword is that long; difflib would take its time
        return ""
    lower = {}
    for c in choices:
        lower.setdefault(c.lower(), c)
    import difflib  # only for a misspelt keyword

    best = difflib.get_close_matches(word.lower(), list(lower), n=1, cutoff=0.6)
    return f" (did you mean '{lower[best[0]]}'?)" if best else ""


def unit_normal(n) -> tuple[float, float, float] | None:
    """n / |n|, or None for a zero (or non-finite) vector. A vector already of unit length
    (to a few ulps) is kept bit for bit, so writing and reading a scene changes nothing."""
    norm = math.sqrt(sum(x * x for x in n))
    if not math.isfinite(norm) or norm == 0.0:
        return None
    if abs(norm - 1.0) <= 4 * sys.float_info.epsilon:
        return tuple(float(x) for x in n)
    return tuple(float(x) / norm for x in n)


def _code(tokens: list[str]) -> list[str]:
    """Tokens before the first one that starts a comment."""
    for k, t in enumerate(tokens):
        if t.startswith("#"):
            return tokens[:k]
    return tokens


def _is_number(tok: str) -> bool:
    return bool(_NUMBER.match(tok))


class _Cursor:
    """Reads one keyword's (or shape line's) arguments left to right; every token carries
    its physical line so a message points where the mistake is."""

    def __init__(self, reader: _TxtReader, name: str, usage: str,
                 toks: list[tuple[str, int]], line: int):
        self.r = reader
        self.name = name  # "`time`", "shape line", "`DBC`" ...
        self.usage = usage
        self.toks = toks
        self.k = 0
        self.line = line  # line of the keyword itself

    def more(self) -> bool:
        return self.k < len(self.toks)

    def peek(self) -> str | None:
        return self.toks[self.k][0] if self.k < len(self.toks) else None

    def _here(self) -> int:
        if self.k < len(self.toks):
            return self.toks[self.k][1]
        return self.toks[-1][1] if self.toks else self.line

    def fail(self, message: str, line: int | None = None):
        raise SceneError(self.r.source, line if line is not None else self._here(), message)

    def _take(self, what: str) -> tuple[str, int]:
        if self.k >= len(self.toks):
            self.fail(f"{self.name} is missing {what} (usage: {self.usage})")
        tok = self.toks[self.k]
        self.k += 1
        return tok

    def word(self, what: str) -> str:
        return self._take(what)[0]

    def number(self, what: str, *, allow_inf: bool = False) -> float:
        tok, line = self._take(what)
        return self.r.to_float(tok, line, f"{self.name} {what}", allow_inf=allow_inf)

    def optional_number(self, what: str, *, allow_inf: bool = False,
                        strict: bool = False) -> float | None:
        """The next token if it is a number, else None. ``strict``: any other token here
        is an error (keyword lines, where nothing but this number can follow)."""
        tok = self.peek()
        if tok is None or (not strict and not _is_number(tok)):
            return None
        return self.number(what, allow_inf=allow_inf)

    def vec3(self, what: str) -> tuple[float, float, float]:
        x, y, z = (self.number(f"{what} {axis}") for axis in "xyz")
        return x, y, z

    def integer(self, what: str) -> int:
        tok, line = self._take(what)
        if not _INTEGER.match(tok):
            if _DIGITS.match(tok):
                self.fail(f"{self.name} {what} is too large ({_q(tok)})", line)
            self.fail(f"{self.name} {what} must be a whole number, got '{_q(tok)}'", line)
        return int(tok)

    def done(self) -> None:
        """Left-over tokens: numbers are ignored with a warning (the original ignores them
        and its own scripts rely on that, e.g. ``ground 0 0.5 50.0``); a word is an error,
        as it is usually a second keyword or a misplaced comment."""
        rest = self.toks[self.k:]
        if not rest:
            return
        for tok, line in rest:
            if not _is_number(tok):
                self.fail(f"{self.name}: unexpected '{_q(tok)}' after its arguments "
                          f"(usage: {self.usage}; start a comment with #)", line)
        shown = " ".join(_q(t) for t, _ in rest[:5])
        if len(rest) > 5:
            shown += f" and {len(rest) - 5} more"
        self.r.warn(rest[0][1], f"{self.name} ignores the extra "
                                f"{'number' if len(rest) == 1 else 'numbers'} "
                                f"{shown} (usage: {self.usage})")
        self.k = len(self.toks)


class _Rows:
    """The tokens of each physical line (``rows[i]``, split when asked for), and where the
    next line with content is: blank and comment lines are found by one regular
    expression over the whole text, so a file of them costs no Python work per line."""

    def __init__(self, text: str):
        self._lines = text.split("\n")
        # with everything from a `#` on removed, exactly the lines whose first token does
        # not start with `#` keep a character that is not whitespace
        code = _FROM_HASH.sub("", text)
        content, line, last, pos = [], 0, 0, 0
        while (m := _NON_SPACE.search(code, pos)) is not None:
            start = m.start()
            line += code.count("\n", last, start)
            last = start
            content.append(line)
            pos = code.find("\n", start) + 1
            if pos == 0:
                break
        self._content = content

    def __len__(self) -> int:
        return len(self._lines)

    def __getitem__(self, i: int) -> list[str]:
        return self._lines[i].split()

    def next_content(self, i: int) -> int:
        """The first line at or after ``i`` that is neither blank nor a comment (or
        ``len(self)`` when there is none)."""
        k = bisect.bisect_left(self._content, i)
        return self._content[k] if k < len(self._content) else len(self._lines)


class _TxtReader:
    def __init__(self, text: str, source):
        self.source = str(source) if source is not None else None
        self.scene_path = source
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        self.rows = _Rows(text)
        self.i = 0
        self.values: dict = {}
        self.lines: dict[str, int] = {}
        self.tuning = list(_TUNING_DEFAULTS)
        self.tuning_lines: list[int | None] = [None] * 6
        self.shapes: list[ShapeSpec] = []
        self.planes: list[PlaneSpec] = []
        self.obstacles: list[MeshObstacleSpec] = []
        self.warnings: list[str] = []
        self.ignored: list[str] = []

    # helpers ------------------------------------------------------------------------------

    def fail(self, line: int | None, message: str):
        raise SceneError(self.source, line, message)

    def warn(self, line: int | None, message: str) -> None:
        where = self.source or "<scene>"
        if line is not None:
            where = f"{where}:{line}"
        self.warnings.append(f"{where}: warning: {message}")

    def to_float(self, tok: str, line: int, what: str, *, allow_inf: bool = False) -> float:
        if not _is_number(tok):
            self.fail(line, f"{what} must be a number, got '{_q(tok)}'")
        x = float(tok)
        if math.isnan(x) or (math.isinf(x) and not (allow_inf and x > 0)):
            extra = " (only the end of a time range may be inf)" if math.isinf(x) else ""
            self.fail(line, f"{what} must be a finite number, got '{_q(tok)}'{extra}")
        return x

    def set(self, key: str, field: str, value, line: int) -> None:
        self.values[field] = value
        self.lines[key] = line

    def cursor(self, kw: str, args: list[str], line: int) -> _Cursor:
        return _Cursor(self, f"`{kw}`", USAGE.get(kw, kw), [(t, line) for t in args], line)

    # main loop ----------------------------------------------------------------------------

    def parse(self) -> SceneSpec:
        while True:
            self.i = self.rows.next_content(self.i)
            if self.i >= len(self.rows):
                break
            line = self.i + 1
            toks = _code(self.rows[self.i])
            self.i += 1
            kw, args = toks[0], toks[1:]
            if kw in IGNORED_KEYWORDS:
                self.ignored.append(" ".join(toks))
                continue
            if kw in NOOP_KEYWORDS:
                self.warn(line, f"`{kw}` has no effect and is ignored (the original program "
                                "does not know it either)")
                continue
            handler = _HANDLERS.get(kw)
            if handler is None:
                hint = suggest(kw, KEYWORDS)
                if not hint and kw in SHAPE_EXTRAS:
                    hint = " (shape extras belong on a shape line)"
                self.fail(line, f"unknown keyword '{_q(kw)}'{hint}")
            handler(self, self.cursor(kw, args, line))
        return self.finish()

    def finish(self) -> SceneSpec:
        t, tl = self.tuning, self.tuning_lines
        for k, key in enumerate(_TUNING_KEYS):
            if tl[k] is not None and k != 4:  # entry 4 (initial eps_v) is not kept
                self.lines[key] = tl[k]
        if t[0] < 0:
            self.fail(tl[0], f"barrier stiffness kappa must be > 0, or 0 for adaptive "
                             f"(got {t[0]!r})")
        if t[4] != t[5]:
            self.warn(tl[4], f"the initial eps_v ({t[4]!r}) differs from the target "
                             f"({t[5]!r}); ipcsim uses the target throughout")
        v = self.values
        v["kappa"] = t[0] if t[0] != 0 else None
        v["dhat"] = t[2]
        v["dhat_start"] = t[1] if t[1] != t[2] else None
        v["dtol"] = t[3]
        v["epsv"] = t[5]
        spec = SceneSpec(
            shapes=tuple(self.shapes),
            planes=tuple(self.planes),
            mesh_obstacles=tuple(self.obstacles),
            source=paths.absolute(self.scene_path) if self.scene_path is not None else None,
            ignored=tuple(self.ignored),
            **v,
        )
        more = validate_scene(spec, source=self.source, lines=self.lines, fmt="txt")
        return replace(spec, warnings=tuple(self.warnings) + more,
                       key_lines=dict(self.lines))

    # files --------------------------------------------------------------------------------

    def resolve(self, written: str, line: int, what: str, exists=paths.is_file) -> Path:
        found = paths.resolve(written, self.scene_path, exists)
        if found is None:
            self.fail(line, paths.not_found_message(what, written, self.scene_path, exists))
        return found

    def resolve_mesh(self, written: str, line: int) -> tuple[Path, str | None]:
        """(resolved mesh path, mesh_kind override). A missing ``x.seg`` / ``x.pt`` falls
        back to ``x.obj`` as in the original, with a warning."""
        suffix = Path(written).suffix.lower()
        if suffix not in MESH_KINDS:
            self.fail(line, f"unknown mesh file extension '{_q(suffix)}' in '{_q(written)}' "
                            "(tetrahedra: .msh, .vtk, .vtu, .ele or none for TetGen; "
                            "surface: .obj; segments: .seg; points: .pt)")
        exists = paths.is_tetgen if suffix in ("", ".ele") else paths.is_file
        found = paths.resolve(written, self.scene_path, exists)
        if found is not None:
            return found, None
        if suffix in (".seg", ".pt"):
            obj = Path(written).with_suffix(".obj").as_posix()
            found = paths.resolve(obj, self.scene_path)
            if found is not None:
                part = "edges" if suffix == ".seg" else "vertices"
                self.warn(line, f"'{_q(written)}' does not exist; using the {part} of "
                                f"'{_q(obj)}' instead (as the original does)")
                return found, MESH_KINDS[suffix]
        what = "TetGen mesh (.node + .ele)" if suffix in ("", ".ele") else "mesh file"
        self.fail(line, paths.not_found_message(what, written, self.scene_path, exists))

    # shape lines --------------------------------------------------------------------------

    def gather(self) -> list[tuple[str, int]]:
        """Tokens of one logical shape line, following ``\\`` continuations. A ``#`` token
        comments out the rest of its physical line, but a ``\\`` inside the comment still
        continues the line (as in the original)."""
        toks: list[tuple[str, int]] = []
        while self.i < len(self.rows):
            row, line = self.rows[self.i], self.i + 1
            self.i += 1
            cont = in_comment = False
            for k, tok in enumerate(row):
                if tok == "\\":
                    cont = True
                    after = _code(row[k + 1:])
                    if after and not in_comment:
                        self.fail(line, f"unexpected '{_q(after[0])}' after the line "
                                        "continuation '\\' (it must end the line)")
                    break
                if in_comment:
                    continue
                if tok.startswith("#"):
                    in_comment = True
                    continue
                toks.append((tok, line))
            if not cont:
                break
        return toks

    def next_content_line(self) -> int | None:
        """Skip blank and comment lines; the index of the next other line, or None."""
        self.i = self.rows.next_content(self.i)
        return self.i if self.i < len(self.rows) else None

    def shape_line(self, toks) -> None:
        path_tok, line = toks[0]
        c = _Cursor(self, "shape line", SHAPE_USAGE, toks[1:], line)
        mesh, kind = self.resolve_mesh(path_tok, line)
        translation = c.vec3("translation")
        rotation = c.vec3("rotation")
        scale = c.vec3("scale")
        idx = len(self.shapes)
        key = f"shapes[{idx}]"
        self.lines[key] = line
        extra: dict = {}
        dbc: list[DirichletSpec] = []
        nbc: list[NeumannSpec] = []
        while c.more():
            tok, tline = c.toks[c.k]
            c.k += 1
            if tok in ("material", "linearVelocity", "angularVelocity", "initVel", "meshSeq"):
                if tok in extra:
                    self.warn(tline, f"`{tok}` appears twice on one shape line; the last "
                                     "one counts")
            e = _Cursor(self, f"`{tok}`", _EXTRA_USAGE.get(tok, ""), c.toks, tline)
            e.k = c.k
            if tok == "material":
                extra[tok] = MaterialSpec(e.number("density"), e.number("Young's modulus"),
                                          e.number("Poisson ratio"))
                self.lines[f"{key}.material"] = tline
            elif tok == "linearVelocity":
                extra[tok] = e.vec3("velocity")
                self.lines[f"{key}.linear_velocity"] = tline
            elif tok == "angularVelocity":
                extra[tok] = e.vec3("angular velocity")
                self.lines[f"{key}.angular_velocity_deg"] = tline
            elif tok == "initVel":
                extra[tok] = InitialVelocitySpec(e.vec3("velocity"), e.vec3("angular velocity"))
                self.lines[f"{key}.init_velocity"] = tline
            elif tok == "meshSeq":
                folder = e.word("a folder")
                extra[tok] = self.resolve(folder, tline, "mesh sequence folder", paths.is_dir)
                self.lines[f"{key}.mesh_sequence"] = tline
            elif tok in ("DBC", "NBC"):
                lo, hi = e.vec3("box min corner"), e.vec3("box max corner")
                if tok == "DBC":
                    v, w = e.vec3("velocity"), e.vec3("angular velocity")
                else:
                    acc = e.vec3("acceleration")
                # optional window [t0, t1): t0 defaults to 0, t1 to +inf
                t0 = e.optional_number("start time")
                t1 = e.optional_number("end time", allow_inf=True) if t0 is not None else None
                rng = (0.0 if t0 is None else t0, INF if t1 is None else t1)
                if tok == "DBC":
                    self.lines[f"{key}.dbc[{len(dbc)}]"] = tline
                    dbc.append(DirichletSpec(lo, hi, v, w, rng, line=tline))
                else:
                    self.lines[f"{key}.nbc[{len(nbc)}]"] = tline
                    nbc.append(NeumannSpec(lo, hi, acc, rng, line=tline))
            elif _is_number(tok):
                c.fail(f"unexpected number '{_q(tok)}' on the shape line: a shape line has "
                       f"exactly 9 numbers before its extras (usage: {SHAPE_USAGE})", tline)
            else:
                c.fail(f"unknown shape extra '{_q(tok)}'{suggest(tok, SHAPE_EXTRAS)} "
                       f"(extras: {', '.join(SHAPE_EXTRAS)})", tline)
            c.k = e.k
        self.shapes.append(ShapeSpec(
            mesh_path=mesh, translation=translation, rotation_deg=rotation, scale=scale,
            material=extra.get("material"), linear_velocity=extra.get("linearVelocity"),
            angular_velocity_deg=extra.get("angularVelocity"), dbc=tuple(dbc), nbc=tuple(nbc),
            init_velocity=extra.get("initVel"), mesh_sequence=extra.get("meshSeq"),
            mesh_kind=kind, path=path_tok, line=line,
        ))

    # keywords -----------------------------------------------------------------------------

    def kw_shapes(self, a: _Cursor) -> None:
        a.word("its word (conventionally `input`)")
        n = a.integer("shape count N")
        a.done()
        if n < 0:
            a.fail(f"`shapes` count must be >= 0, got {n}")
        for k in range(n):
            if self.next_content_line() is None:
                a.fail(f"`shapes` declares {n} shape lines but the file ends after {k}",
                       a.line)
            first = _code(self.rows[self.i])[0]
            if first in KEYWORDS and paths.resolve(first, self.scene_path,
                                                   paths.is_tetgen) is None:
                a.fail(f"expected shape line {k + 1} of {n} here, found the keyword "
                       f"`{_q(first)}`: the `shapes` block at line {a.line} declares {n} shapes "
                       f"but has only {k} shape line{'s' if k != 1 else ''}", self.i + 1)
            toks = self.gather()
            if not toks:
                a.fail("empty shape line after a line continuation", self.i)
            self.shape_line(toks)

    def kw_shape(self, a: _Cursor) -> None:
        a.word("its word (conventionally `input`)")
        written = a.word("a mesh file")
        a.done()
        mesh, kind = self.resolve_mesh(written, a.line)
        self.lines[f"shapes[{len(self.shapes)}]"] = a.line
        self.shapes.append(ShapeSpec(mesh_path=mesh, mesh_kind=kind, path=written,
                                     line=a.line))

    def kw_shapeMatrix(self, a: _Cursor) -> None:
        a.word("its word (conventionally `input`)")
        counts = [a.integer(f"count n{axis}") for axis in "xyz"]
        origin = [a.optional_number(f"position {axis}", strict=True) for axis in "xyz"]
        a.done()
        if any(n < 0 for n in counts):
            a.fail(f"`shapeMatrix` counts must be >= 0, got {counts}")
        if math.prod(counts) > _MAX_MATRIX_COPIES:
            a.fail(f"`shapeMatrix` would create {math.prod(counts)} copies "
                   f"(at most {_MAX_MATRIX_COPIES})")
        if self.next_content_line() is None:
            a.fail("`shapeMatrix` needs its shape line on the following line")
        toks = self.gather()
        path_tok, line = toks[0]
        c = _Cursor(self, "shapeMatrix line", USAGE["shapeMatrix"], toks[1:], line)
        mesh, kind = self.resolve_mesh(path_tok, line)
        spacing = c.vec3("spacing")
        rotation = c.vec3("rotation")
        scale = c.vec3("scale")
        material = None
        if c.peek() == "material":
            c.k += 1
            material = MaterialSpec(c.number("density"), c.number("Young's modulus"),
                                    c.number("Poisson ratio"))
        if c.more() and not _is_number(c.peek()):
            c.fail(f"a shapeMatrix line takes only the `material` extra, got '{_q(c.peek())}' "
                   "(its copies carry no velocities or boundary conditions)")
        c.done()
        if math.prod(counts) == 0:
            self.warn(a.line, f"`shapeMatrix` with counts {counts} creates no shapes")
        px, py, pz = (0.0 if o is None else o for o in origin)
        # copies at (px + dx i, py + dy j, pz + dz k), x outer, y, z inner (as the original)
        for i in range(counts[0]):
            for j in range(counts[1]):
                for k in range(counts[2]):
                    t = (px + spacing[0] * i, py + spacing[1] * j, pz + spacing[2] * k)
                    self.lines[f"shapes[{len(self.shapes)}]"] = line
                    if material is not None:
                        self.lines[f"shapes[{len(self.shapes)}].material"] = line
                    self.shapes.append(ShapeSpec(
                        mesh_path=mesh, translation=t, rotation_deg=rotation, scale=scale,
                        material=material, mesh_kind=kind, path=path_tok, line=line))

    def kw_ground(self, a: _Cursor) -> None:
        mu = a.number("friction")
        h = a.number("height")
        a.done()
        self.lines[f"planes[{len(self.planes)}]"] = a.line
        self.planes.append(PlaneSpec("ground", (0.0, h, 0.0), (0.0, 1.0, 0.0), mu, 0.0,
                                     line=a.line))

    def kw_halfSpace(self, a: _Cursor) -> None:
        o = a.vec3("origin")
        n = a.vec3("normal")
        stiffness = a.number("stiffness")
        mu = a.number("friction")
        a.done()
        unit = unit_normal(n)
        if unit is None:
            a.fail(f"`halfSpace` normal {n} is the zero vector", a.line)
        self.lines[f"planes[{len(self.planes)}]"] = a.line
        self.planes.append(PlaneSpec("halfSpace", o, unit, mu, stiffness, line=a.line))

    def kw_meshCO(self, a: _Cursor) -> None:
        written = a.word("a mesh file")
        pos = a.vec3("position")
        size = a.number("size")
        stiffness = a.number("stiffness")
        mu = a.number("friction")
        rot = (0.0, 0.0, 0.0)
        if a.peek() == "rotate":
            a.k += 1
            rot = a.vec3("rotate")
        a.done()
        if Path(written).suffix.lower() != ".obj":
            a.fail(f"`meshCO` needs an .obj triangle mesh, got '{_q(written)}'", a.line)
        mesh = self.resolve(written, a.line, "meshCO mesh file")
        self.lines[f"mesh_obstacles[{len(self.obstacles)}]"] = a.line
        self.obstacles.append(MeshObstacleSpec(mesh, pos, size, stiffness, mu, rot,
                                               path=written, line=a.line))

    def kw_time(self, a: _Cursor) -> None:
        self.set("time.duration", "duration", a.number("duration"), a.line)
        dt = a.optional_number("time step dt", strict=True)
        if dt is not None:
            self.set("time.dt", "dt", dt, a.line)
        a.done()

    def kw_density(self, a: _Cursor) -> None:
        self.set("material.density", "density", a.number("density"), a.line)
        a.done()

    def kw_stiffness(self, a: _Cursor) -> None:
        self.set("material.youngs_modulus", "youngs_modulus", a.number("Young's modulus"),
                 a.line)
        self.set("material.poisson_ratio", "poisson_ratio", a.number("Poisson ratio"), a.line)
        a.done()

    def kw_energy(self, a: _Cursor) -> None:
        name = a.word("an energy name")
        if name not in ENERGIES:
            a.fail(f"unknown energy '{_q(name)}'{suggest(name, ENERGIES)} "
                   f"(choose {' or '.join(ENERGIES)})", a.line)
        self.set("material.energy", "energy", name, a.line)
        a.done()

    def kw_timeIntegration(self, a: _Cursor) -> None:
        name = a.word("an integrator (BE, NM or BDF2)")
        if name not in INTEGRATORS:
            a.fail(f"unknown time integrator '{_q(name)}'{suggest(name, INTEGRATORS)} "
                   "(choose BE, NM or BDF2)", a.line)
        self.set("integrator.type", "integrator", name, a.line)
        if name == "NM":
            beta = a.optional_number("beta", strict=True)
            if beta is not None:
                self.set("integrator.newmark_beta", "newmark_beta", beta, a.line)
                gamma = a.optional_number("gamma", strict=True)
                if gamma is not None:
                    self.set("integrator.newmark_gamma", "newmark_gamma", gamma, a.line)
        a.done()

    def kw_timeTolerance(self, a: _Cursor) -> None:
        """ipcsim's extension: adaptive time steps to this local error (relative to l)."""
        self.set("time.tolerance", "time_tolerance", a.number("relative error"), a.line)
        a.done()

    def kw_turnOffGravity(self, a: _Cursor) -> None:
        a.done()
        self.set("scene.gravity", "gravity", False, a.line)

    def kw_dampingStiff(self, a: _Cursor) -> None:
        k = a.number("stiffness")
        a.done()
        if k < 0:  # the original clamps: negative damping would add energy
            self.warn(a.line, f"`dampingStiff` {k!r} < 0 is taken as 0")
            k = 0.0
        self.set("integrator.damping_stiff", "damping_stiff", k, a.line)

    def kw_dampingRatio(self, a: _Cursor) -> None:
        r = a.number("ratio")
        a.done()
        if not 0 <= r <= 1:  # the original clamps to [0, 1]
            clamped = min(max(r, 0.0), 1.0)
            self.warn(a.line, f"`dampingRatio` {r!r} is outside [0, 1]; taken as {clamped!r}")
            r = clamped
        self.set("integrator.damping_ratio", "damping_ratio", r, a.line)

    def kw_selfCollisionOn(self, a: _Cursor) -> None:
        a.done()
        self.set("contact.self_collision", "self_collision", True, a.line)

    def kw_selfCollisionOff(self, a: _Cursor) -> None:
        a.done()
        self.set("contact.self_collision", "self_collision", False, a.line)

    def kw_selfFric(self, a: _Cursor) -> None:
        self.set("contact.self_friction", "self_friction", a.number("friction"), a.line)
        a.done()

    def _tune(self, slots, value: float, line: int) -> None:
        for s in slots:
            self.tuning[s] = value
            self.tuning_lines[s] = line

    def kw_dHat(self, a: _Cursor) -> None:
        # dHat writes both the initial and the target entry of `tuning`: no homotopy
        self._tune((1, 2), a.number("distance"), a.line)
        a.done()

    def kw_epsv(self, a: _Cursor) -> None:
        self._tune((4, 5), a.number("velocity"), a.line)
        a.done()

    def kw_kappa(self, a: _Cursor) -> None:
        k = a.number("barrier stiffness")
        a.done()
        if not k > 0:
            a.fail(f"`kappa` must be > 0, got {k!r} (leave it out for adaptive stiffness)",
                   a.line)
        self._tune((0,), k, a.line)

    def kw_dHatAbs(self, a: _Cursor) -> None:
        self.set("contact.dhat_abs", "dhat_abs", a.number("distance"), a.line)
        a.done()

    def kw_epsvAbs(self, a: _Cursor) -> None:
        self.set("contact.epsv_abs", "epsv_abs", a.number("velocity"), a.line)
        a.done()

    def kw_fricIterAmt(self, a: _Cursor) -> None:
        self.set("contact.friction_iterations", "friction_iterations",
                 a.integer("iteration count"), a.line)
        a.done()

    def _following_numbers(self, a: _Cursor, kw: str) -> list[tuple[float, int]]:
        """The N numbers after ``tol N`` / ``tuning N``, read from the following lines
        (any whitespace; blank and comment lines skipped)."""
        n = a.integer("count N")
        if a.more() and not a.peek().startswith("#"):
            a.fail(f"`{kw} {n}` takes its {n} value(s) from the following lines, not from "
                   f"its own line (the original silently ignores '{_q(a.peek())}' here); move "
                   "them to the next line", a.line)
        if n < (1 if kw == "tol" else 0):
            a.fail(f"`{kw}` count must be >= {1 if kw == 'tol' else 0}, got {n}", a.line)
        vals: list[tuple[float, int]] = []
        while len(vals) < n:
            self.i = self.rows.next_content(self.i)
            if self.i >= len(self.rows):
                a.fail(f"`{kw} {n}` expects {n} numbers on the following lines, but the file "
                       f"ends after {len(vals)}", a.line)
            line = self.i + 1
            toks = _code(self.rows[self.i])
            self.i += 1
            for tok in toks:
                if len(vals) == n:
                    self.fail(line, f"unexpected '{_q(tok)}' after the {n} value(s) of `{kw}` "
                                    f"(line {a.line}); put the next keyword on its own line")
                if not _is_number(tok):
                    self.fail(line, f"`{kw} {n}` (line {a.line}) expects {n} numbers on the "
                                    f"following lines; got '{_q(tok)}' after {len(vals)}")
                vals.append((self.to_float(tok, line, f"`{kw}` value"), line))
        return vals

    def kw_tol(self, a: _Cursor) -> None:
        vals = self._following_numbers(a, "tol")
        self.set("solver.newton_tol", "newton_tol", tuple(v for v, _ in vals), a.line)

    def kw_tuning(self, a: _Cursor) -> None:
        vals = self._following_numbers(a, "tuning")
        if len(vals) > 6:
            self.warn(vals[6][1], f"`tuning` uses 6 values; ignored the other {len(vals) - 6}")
        # the vector is replaced as a whole; missing trailing entries take built-in values
        for s in range(6):
            if s < len(vals):
                self.tuning[s], self.tuning_lines[s] = vals[s]
            else:
                self.tuning[s], self.tuning_lines[s] = _TUNING_DEFAULTS[s], a.line

    def kw_kappaMinMultiplier(self, a: _Cursor) -> None:
        self.set("contact.kappa_min_multiplier", "kappa_min_multiplier",
                 a.number("multiplier"), a.line)
        a.done()

    def kw_useAbsParameters(self, a: _Cursor) -> None:
        a.done()
        self.set("contact.use_abs_parameters", "use_abs_parameters", True, a.line)

    def _time_range(self, a: _Cursor, key: str, field: str) -> None:
        t0 = a.number("start time")
        t1 = a.optional_number("end time", allow_inf=True, strict=True)
        a.done()
        self.set(key, field, (t0, INF if t1 is None else t1), a.line)

    def kw_DBCTimeRange(self, a: _Cursor) -> None:
        self._time_range(a, "scene.dbc_time_range", "dbc_time_range")

    def kw_NBCTimeRange(self, a: _Cursor) -> None:
        self._time_range(a, "scene.nbc_time_range", "nbc_time_range")

    def kw_warmStart(self, a: _Cursor) -> None:
        self.set("integrator.warm_start", "warm_start", a.integer("option"), a.line)
        a.done()

    def kw_constraintSolver(self, a: _Cursor) -> None:
        name = a.word("a solver name")
        a.done()
        if name not in SOLVER_NAMES:
            a.fail(f"unknown constraint solver '{_q(name)}'{suggest(name, SOLVER_NAMES)} "
                   "(interiorPoint, alias IP: the IPC barrier method; SQP, QP: the "
                   "comparison baselines)", a.line)
        self.set("solver.constraint_solver", "constraint_solver", SOLVER_NAMES[name], a.line)

    def kw_constraintType(self, a: _Cursor) -> None:
        name = a.word("a constraint type")
        a.done()
        if name in UNSUPPORTED_CONSTRAINT_TYPES:
            a.fail(f"constraint type '{name}' is not implemented by ipcsim (it implements "
                   f"{', '.join(CONSTRAINT_TYPES)})", a.line)
        if name not in CONSTRAINT_TYPES:
            a.fail(f"unknown constraint type '{name}'"
                   f"{suggest(name, (*CONSTRAINT_TYPES, *UNSUPPORTED_CONSTRAINT_TYPES))}",
                   a.line)
        self.set("solver.constraint_type", "constraint_type", name, a.line)

    def kw_constraintOffset(self, a: _Cursor) -> None:
        self.set("solver.constraint_offset", "constraint_offset", a.number("offset"), a.line)
        a.done()

    def kw_useActiveSetConvergence(self, a: _Cursor) -> None:
        a.done()
        self.set("solver.active_set_convergence", "active_set_convergence", True, a.line)

    def kw_noActiveSetConvergence(self, a: _Cursor) -> None:
        a.done()
        self.set("solver.active_set_convergence", "active_set_convergence", False, a.line)

    def kw_section(self, a: _Cursor) -> None:
        names = [t for t, _ in a.toks]
        if names[:1] == ["end"]:
            return  # `section end` met while parsing: nothing to close
        for name in names:
            if name not in SOLVER_NAMES:
                a.fail(f"`section` names solvers, got '{_q(name)}'"
                       f"{suggest(name, (*SOLVER_NAMES, 'end'))}", a.line)
        selected = self.values.get("constraint_solver", "interiorPoint")
        if any(SOLVER_NAMES[name] == selected for name in names):
            return  # the solver selected so far is listed: parse normally (as the original)
        # otherwise skip every line up to and including `section end` (a bare `section`
        # skips too)
        while True:
            self.i = self.rows.next_content(self.i)
            if self.i >= len(self.rows):
                break
            row = self.rows[self.i]
            self.i += 1
            if row[:2] == ["section", "end"]:
                return
        self.warn(a.line, f"`section {' '.join(names)}` has no `section end`; the rest of "
                          "the file is skipped")

    def kw_size(self, a: _Cursor) -> None:
        self.set("scene.size", "size", a.number("size"), a.line)
        a.done()

    def kw_rotateModel(self, a: _Cursor) -> None:
        axis = a.vec3("axis")
        deg = a.number("angle")
        a.done()
        self.set("scene.rotate_model", "rotate_model", (*axis, deg), a.line)

    def kw_handleRatio(self, a: _Cursor) -> None:
        self.set("scene.handle_ratio", "handle_ratio", a.number("ratio"), a.line)
        a.done()

    def kw_restart(self, a: _Cursor) -> None:
        written = a.word("a status file")
        a.done()
        self.set("scene.restart", "restart", self.resolve(written, a.line, "restart file"),
                 a.line)

    def kw_script(self, a: _Cursor) -> None:
        name = a.word("a script name")
        if name not in SUPPORTED_SCRIPTS:
            a.fail(f"script '{_q(name)}' is not supported{suggest(name, SUPPORTED_SCRIPTS)}; "
                   f"ipcsim implements: {', '.join(SUPPORTED_SCRIPTS)}", a.line)
        params: tuple[float, ...] = ()
        if a.more() and not a.peek().startswith("#"):
            n = a.integer("parameter count N")
            if n < 0:
                a.fail(f"`script` parameter count must be >= 0, got {n}", a.line)
            params = tuple(a.number(f"parameter {k + 1}") for k in range(n))
        a.done()
        self.set("scene.script", "script", name, a.line)
        self.set("scene.script_params", "script_params", params, a.line)

    def kw_linearSolver(self, a: _Cursor) -> None:
        name = a.word("a solver name")
        a.done()
        key = name.lower()
        if key == "auto":
            self.set("solver.linear_solver", "linear_solver", None, a.line)
            return
        if key not in LINEAR_SOLVERS:
            a.fail(f"unknown linear solver '{_q(name)}'{suggest(name, LINEAR_SOLVERS)} "
                   f"(choose {', '.join(LINEAR_SOLVERS)} or auto)", a.line)
        self.set("solver.linear_solver", "linear_solver", key, a.line)

    def kw_appendStr(self, a: _Cursor) -> None:
        word = a.word("a word")
        self.set("output.append_str", "append_str", word, a.line)
        a.done()

    def kw_playBackSpeed(self, a: _Cursor) -> None:
        s = a.number("speed")
        a.done()
        if s <= 0:  # the original's rule
            self.warn(a.line, f"`playBackSpeed` {s!r} <= 0 is taken as 1")
            s = 1.0
        self.set("output.playback_speed", "playback_speed", s, a.line)


_EXTRA_USAGE = {
    "material": "material <density> <E> <nu>",
    "linearVelocity": "linearVelocity <vx> <vy> <vz>",
    "angularVelocity": "angularVelocity <wx> <wy> <wz> (deg/s)",
    "DBC": "DBC <x0> <y0> <z0> <x1> <y1> <z1> <vx> <vy> <vz> <wx> <wy> <wz> [<t0> [<t1>]]",
    "NBC": "NBC <x0> <y0> <z0> <x1> <y1> <z1> <ax> <ay> <az> [<t0> [<t1>]]",
    "initVel": "initVel <vx> <vy> <vz> <wx> <wy> <wz>",
    "meshSeq": "meshSeq <folder>",
}

_ALIASES = {"minBarrierStiffnessScale": "kappaMinMultiplier", "linSysSolver": "linearSolver"}
_HANDLERS = {name: getattr(_TxtReader, f"kw_{_ALIASES.get(name, name)}")
             for name in USAGE}
KEYWORDS = tuple(USAGE) + IGNORED_KEYWORDS + NOOP_KEYWORDS


def parse_txt(text: str, source=None) -> SceneSpec:
    """Parse the text of an IPC script. ``source`` (the script's path) names the file in
    messages and anchors relative paths; it is not read."""
    return _TxtReader(text, source).parse()
