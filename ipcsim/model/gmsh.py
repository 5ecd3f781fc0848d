"""Gmsh ASCII files read from their text: node tags always, and for MSH 4.1 (the format
of the original's tet meshes) the whole mesh.

Two uses:

* ``check_gmsh_tags`` (``mesh_check``) reads the node tags of MSH 2.2 and 4.1 files itself:
  meshio maps a tag that names no node onto some other node;
* ``read_tet_mesh`` takes points and tets of an MSH 4.1 ASCII file from here instead of
  from meshio, whose import (every format it knows and its command line) costs about
  40 ms, 5 % of a tiny scene's whole run. What this reader does not take on — MSH
  2.2, binary files, parametric nodes, node tags other than 1..n in file order, a file
  without tetrahedra — goes to meshio, which reads such files the same way (tests
  compare the two on every example mesh).

MSH 4.1 layout (``$Nodes``): ``numEntityBlocks numNodes minTag maxTag``, then per block
``entityDim entityTag parametric numNodesInBlock``, its node tags one per line, then one
``x y z`` line per node; (``$Elements``): ``numEntityBlocks numElements minTag maxTag``,
then per block ``entityDim entityTag elementType numElementsInBlock`` and one
``tag node...`` line per element. Element type 4 is the 4-node tetrahedron, type 2 the
3-node triangle (the elements of a 2D scene's meshes).
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

TETRAHEDRON = 4  # Gmsh's element type of the 4-node tetrahedron
TRIANGLE = 2  # ... and of the 3-node triangle


class GmshText(Struct, frozen=True):
    """What an ASCII Gmsh file holds: ``version`` ("2.2" or "4.1"), its node tags in file
    order, each element block as (element type, rows ``tag node-tag...``) and, for 4.1,
    the nodes' coordinates (None where a block is parametric)."""

    version: str
    node_tags: np.ndarray
    blocks: list[tuple[int, np.ndarray]]
    points: np.ndarray | None = None

    def tetrahedra(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(points (n, 3), tets (m, 4) 0-based) when this reader can give them (module
        docstring), else None."""
        return self.elements(TETRAHEDRON, 4)

    def triangles(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(points (n, 3), triangles (m, 3) 0-based), as ``tetrahedra``."""
        return self.elements(TRIANGLE, 3)

    def elements(self, kind: int, width: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(points, elements of Gmsh type ``kind`` with ``width`` nodes, 0-based), or
        None where this reader cannot give them (parametric nodes, tags other than 1..n
        in file order, no such elements)."""
        n = len(self.node_tags)
        if self.points is None or not np.array_equal(self.node_tags, np.arange(1, n + 1)):
            return None
        cells = [rows[:, 1:] for k, rows in self.blocks if k == kind]
        if not cells or any(c.shape[1] != width for c in cells):
            return None
        return self.points, np.concatenate(cells) - 1


def section(text: str, name: str) -> list[str] | None:
    """The lines between ``$name`` and ``$Endname``, or None when there is no such section."""
    begin = text.find(f"${name}")
    if begin < 0:
        return None
    body = text.find("\n", begin) + 1
    end = text.find(f"$End{name}", body)
    return text[body:end if end >= 0 else len(text)].split("\n")


def parse(text: str) -> GmshText | None:
    """The ASCII Gmsh file ``text``; None for a binary file, another version, or one this
    parser cannot follow (meshio's reader then says what is wrong)."""
    fmt = section(text, "MeshFormat")
    nodes, elements = section(text, "Nodes"), section(text, "Elements")
    if not fmt or nodes is None or elements is None or len(fmt[0].split()) < 2:
        return None
    version, file_type = fmt[0].split()[:2]
    if file_type != "0" or version not in ("2.2", "4.1"):
        return None
    try:
        if version == "4.1":
            return _parse_v41(nodes, elements)
        return _parse_v22(nodes, elements)
    except (ValueError, IndexError):
        return None


def _numbers(lines: list[str], dtype, per_line: int | None = None) -> np.ndarray:
    """The numbers of ``lines`` (``per_line``: how many each line must hold)."""
    tokens = " ".join(lines).split()
    if per_line is not None and len(tokens) != per_line * len(lines):
        raise ValueError("unexpected number of values")
    return np.array(tokens, dtype=dtype)


def _parse_v41(nodes: list[str], elements: list[str]) -> GmshText:
    tags, coordinates, parametric, i = [], [], False, 1
    for _ in range(int(nodes[0].split()[0])):
        header = nodes[i].split()  # entityDim entityTag parametric numNodesInBlock
        n = int(header[3])
        tags.append(_numbers(nodes[i + 1:i + 1 + n], np.int64, 1))
        if header[2] != "0":
            parametric = True  # x y z then u (v, w): left to meshio
        else:
            coordinates.append(_numbers(nodes[i + 1 + n:i + 1 + 2 * n], np.float64, 3))
        i += 1 + 2 * n
    blocks, i = [], 1
    for _ in range(int(elements[0].split()[0])):
        header = elements[i].split()  # entityDim entityTag elementType numElementsInBlock
        n = int(header[3])
        rows = _numbers(elements[i + 1:i + 1 + n], np.int64)
        blocks.append((int(header[2]), rows.reshape(n, -1) if n else rows.reshape(0, 2)))
        i += 1 + n
    node_tags = np.concatenate(tags) if tags else np.zeros(0, np.int64)
    points = None
    if not parametric:
        points = (np.concatenate(coordinates) if coordinates else np.zeros(0)).reshape(-1, 3)
    return GmshText("4.1", node_tags, blocks, points)


def _parse_v22(nodes: list[str], elements: list[str]) -> GmshText:
    """Node tags and one block per element (MSH 2.2: ``tag type ntags tag... node...``)."""
    n = int(nodes[0])
    tags = np.array([row.split(maxsplit=1)[0] for row in nodes[1:1 + n]], dtype=np.int64)
    blocks = []
    for row in elements[1:1 + int(elements[0])]:
        v = [int(t) for t in row.split()]
        blocks.append((v[1], np.array([[v[0], *v[3 + v[2]:]]], dtype=np.int64)))
    return GmshText("2.2", tags, blocks)
