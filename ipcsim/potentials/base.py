"""What every term of the incremental potential looks like to the solver.

A term is a frozen value with

    value(x, ctx) -> float
    gradient(x, ctx) -> (3n,)
    hessian(x, ctx) -> Triplets       every local block already projected to PSD
                                      (BlockHessian for the contact pairs' 12 × 12 blocks)

and, where it bounds the line search, ``max_step(x, p, ctx) -> α ∈ [0, 1]``. ``x`` is the
(n, 3) array of all vertex positions (DOF 3i+a is vertex i, axis a) and ``ctx`` the frozen
``StepContext`` of the step: everything a term needs beyond x. A term's answer depends on
its arguments alone; nothing is assigned to a term after it is built.

``constant_pattern`` marks terms whose Hessian triplets have the same index arrays on every
call (assembly keeps their sparsity pattern).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, ClassVar, Protocol

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from ..kernels.algebra import assembly as ka
from ..kernels.algebra.assembly import block_triplet_indices
from ..kernels.algebra.scatter import block_matvec

if TYPE_CHECKING:
    import scipy.sparse as sp

    from ..contact.collisions import Collisions
    from ..contact.friction_lag import FrictionLag


class Triplets(Struct, frozen=True):
    """A sparse matrix as COO triplets, ``scale`` times (rows, cols, vals); duplicates
    are summed by ``tocsr``. ``scaled(w)`` changes the factor only, so weighting a large
    Hessian copies nothing."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    scale: float = 1.0

    @staticmethod
    def empty() -> "Triplets":
        z = np.zeros(0, dtype=np.int64)
        return Triplets(z, z, np.zeros(0))

    @property
    def size(self) -> int:
        return len(self.rows)

    @property
    def pattern_key(self):
        """What stays the same object while the pattern does (assembly keeps it)."""
        return self.rows

    def pattern_chunks(self):
        """(rows, cols) in pieces that together cover every entry in order."""
        yield self.rows, self.cols

    @property
    def values(self) -> np.ndarray:
        """The entries' values, the scale applied."""
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    @staticmethod
    def concat(parts: list) -> "Triplets":
        parts = [p for p in parts if p.size]
        if not parts:
            return Triplets.empty()
        return Triplets(
            np.concatenate([p.rows for p in parts]),
            np.concatenate([p.cols for p in parts]),
            np.concatenate([p.values for p in parts]),
        )

    def scaled(self, w: float) -> "Triplets":
        """The same triplets, w times."""
        return self if w == 1.0 else Triplets(self.rows, self.cols, self.vals, self.scale * w)

    def tocsr(self, n_dofs: int) -> "sp.csr_matrix":
        import scipy.sparse as sp  # only for whoever asks for the matrix (tests, checks)

        return sp.csr_matrix((self.values, (self.rows, self.cols)), shape=(n_dofs, n_dofs))

    def slots_in(self, free_index, indptr, indices) -> np.ndarray:
        """Each triplet's slot in a CSC pattern over free DOFs that holds it (int32, −1
        where its row or column is kinematic), for ``scatter_into``."""
        return ka.csc_slots(self.rows, self.cols, free_index, indptr, indices)

    def scatter_into(self, data, slots, free_index, p, coupling) -> None:
        """data[slots[t]] += scale·vals[t] (a constant pattern's CSC slots, −1 where a row
        or column is kinematic); free rows' entries in kinematic columns go to coupling."""
        ka.scatter_into_pattern(data, slots, self.vals, self.scale, self.rows, self.cols,
                                free_index, p, coupling)

    def add_dense(self, A, free_index, p, coupling) -> None:
        """A[r, c] += the entries of free rows and columns (a small system's dense
        matrix); free rows' entries in kinematic columns go to coupling."""
        ka.add_triplets_dense(A, self.rows, self.cols, self.vals, float(self.scale),
                              free_index, p, coupling)

    def count_into(self, free_index, p, coupling, counts) -> None:
        """Count the entries a merge keeps per free column (``kernels/algebra/assembly.py``)."""
        ka.count_kept_columns(self.rows, self.cols, self.vals, float(self.scale), free_index,
                              p, coupling, counts)

    def bucket_into(self, free_index, fill, bucket_rows, bucket_vals) -> None:
        """Put the kept entries in their columns' buckets, in order."""
        ka.bucket_kept(self.rows, self.cols, self.vals, float(self.scale), free_index, fill,
                       bucket_rows, bucket_vals)


class BlockHessian(Struct, frozen=True, eq=False):
    """A sparse matrix as 12 × 12 blocks over 4-vertex stencils (the contact pairs),
    ``scale`` times: block k is vals[144 k : 144 (k + 1)], row-major over the 12 DOFs of
    stencils[k]; blocks that share DOFs are summed. As triplets it would carry a row and
    a column per entry (16 bytes with the value, against 8): in heavy contact, tens of
    millions of entries. The merge into the Newton matrix works out rows and columns
    ``CHUNK`` blocks at a time; ``rows`` and ``cols`` are made whole for whoever asks."""

    stencils: np.ndarray  # (k, 4) int64
    vals: np.ndarray  # (144 k,)
    scale: float = 1.0
    CHUNK: ClassVar[int] = 8192  # blocks per piece: 9 MB of rows and columns

    def _pieces(self):
        """``Triplets`` of CHUNK blocks at a time, in order (their rows and columns made
        only for the piece)."""
        for lo in range(0, len(self.stencils), self.CHUNK):
            hi = min(lo + self.CHUNK, len(self.stencils))
            rows, cols = block_triplet_indices(self.stencils[lo:hi])
            yield Triplets(rows, cols, self.vals[144 * lo:144 * hi], self.scale)

    @property
    def size(self) -> int:
        return len(self.vals)

    @property
    def rows(self) -> np.ndarray:
        return block_triplet_indices(self.stencils)[0]

    @property
    def cols(self) -> np.ndarray:
        return block_triplet_indices(self.stencils)[1]

    @property
    def values(self) -> np.ndarray:
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    def scaled(self, w: float) -> "BlockHessian":
        return self if w == 1.0 else replace(self, scale=self.scale * w)

    def tocsr(self, n_dofs: int) -> "sp.csr_matrix":
        return Triplets(*block_triplet_indices(self.stencils), self.values).tocsr(n_dofs)

    def add_dense(self, A, free_index, p, coupling) -> None:
        """As ``Triplets.add_dense``, block by block."""
        ka.add_blocks_dense(A, self.vals, float(self.scale), self.stencils, free_index, p,
                            coupling)

    def count_into(self, free_index, p, coupling, counts) -> None:
        """As ``Triplets.count_into``, a piece at a time."""
        for piece in self._pieces():
            piece.count_into(free_index, p, coupling, counts)

    def bucket_into(self, free_index, fill, bucket_rows, bucket_vals) -> None:
        for piece in self._pieces():
            piece.bucket_into(free_index, fill, bucket_rows, bucket_vals)


class ElementHessian(Struct, frozen=True, eq=False):
    """A Hessian of per-element blocks on a constant pattern, evaluated at ``x`` when it
    is used: ``element_values(x, lo, hi)`` gives the entries of elements lo..hi−1 (block
    after block) and ``element_pattern(elements)`` their (rows, cols). Assembly builds the
    pattern and adds the values ``CHUNK`` elements at a time, so neither the values nor
    the index arrays of all blocks exist at once (144 of each per tet: 230 MB of values
    and as much of indices for 200 K tets); ``rows``, ``cols`` and ``vals`` build them for
    whoever asks."""

    elements: np.ndarray  # (m, nv) vertex ids; the same array on every call
    x: np.ndarray
    element_values: Callable[[np.ndarray, int, int], np.ndarray]
    element_pattern: Callable[[np.ndarray], tuple]
    scale: float = 1.0
    CHUNK: ClassVar[int] = 1024  # elements per evaluation: 1.2 MB of values for tets, in cache

    @property
    def n_elements(self) -> int:
        return len(self.elements)

    @property
    def block(self) -> int:
        return (3 * self.elements.shape[1]) ** 2

    @property
    def size(self) -> int:
        return self.block * self.n_elements

    @property
    def pattern_key(self):
        return self.elements

    def pattern_chunks(self):
        for lo in range(0, self.n_elements, self.CHUNK):
            yield self.element_pattern(self.elements[lo:lo + self.CHUNK])

    @property
    def rows(self) -> np.ndarray:
        return self.element_pattern(self.elements)[0]

    @property
    def cols(self) -> np.ndarray:
        return self.element_pattern(self.elements)[1]

    @property
    def vals(self) -> np.ndarray:
        return self.element_values(self.x, 0, self.n_elements)

    @property
    def values(self) -> np.ndarray:
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    def scaled(self, w: float) -> "ElementHessian":
        return self if w == 1.0 else replace(self, scale=self.scale * w)

    def kept(self) -> "ElementHessian":
        """The same Hessian with its values evaluated now and kept (damping's, for a step)."""
        return replace(self, element_values=_KeptValues(self.vals, self.block))

    def tocsr(self, n_dofs: int) -> "sp.csr_matrix":
        rows, cols = self.element_pattern(self.elements)
        return Triplets(rows, cols, self.values).tocsr(n_dofs)

    def slots_in(self, free_index, indptr, indices) -> np.ndarray:
        """The blocks' slots in a CSC pattern over free DOFs that holds them: one per
        (element, row vertex, column), a vertex's three rows being adjacent
        (``kernels/assembly.element_block_slots``). A vertex's DOFs must be free or
        kinematic together, as Newton's masks (one per vertex) make them."""
        by_vertex = free_index.reshape(-1, 3)
        first = by_vertex[:, :1]
        if not np.array_equal(by_vertex[:, 1:], np.where(first < 0, -1, first + [1, 2])):
            raise ValueError("element blocks need each vertex's three DOFs free (numbered "
                             "consecutively) or kinematic together")
        return ka.element_block_slots(self.elements, free_index, indptr, indices)

    def add_dense(self, A, free_index, p, coupling) -> None:
        """As ``Triplets.add_dense``, one chunk of elements at a time."""
        for lo in range(0, self.n_elements, self.CHUNK):
            hi = min(lo + self.CHUNK, self.n_elements)
            ka.add_blocks_dense(A, self.element_values(self.x, lo, hi), float(self.scale),
                                self.elements[lo:hi], free_index, p, coupling)

    def scatter_into(self, data, slots, free_index, p, coupling) -> None:
        """As ``Triplets.scatter_into`` (with ``slots_in``'s slots), one chunk of elements
        at a time."""
        nv = self.elements.shape[1]
        b = nv * 3 * nv  # slots per element
        for lo in range(0, self.n_elements, self.CHUNK):
            hi = min(lo + self.CHUNK, self.n_elements)
            ka.scatter_element_blocks(data, slots[b * lo:b * hi],
                                      self.element_values(self.x, lo, hi), self.scale,
                                      self.elements[lo:hi], free_index, p, coupling)


class _KeptValues(Struct, frozen=True, eq=False):
    """A block-strided slice of Hessian values kept from one evaluation."""

    vals: np.ndarray
    block: int

    def __call__(self, x, lo: int, hi: int) -> np.ndarray:
        return self.vals[self.block * lo:self.block * hi]


class LaggedDamping(Struct, frozen=True, eq=False):
    """Rayleigh damping frozen at the start of a step: D = (k/h)·∇²Ψ(xₙ)."""

    x_start: np.ndarray  # (n, 3) xₙ
    triplets: "ElementHessian"  # D as blocks on the elastic Hessian's pattern, values kept

    def times(self, v: np.ndarray) -> np.ndarray:
        """D v for a flat (3n,) v, block by block (``kernels/scatter.block_matvec``)."""
        D = self.triplets
        return block_matvec(D.vals, float(D.scale), D.elements, v)


class StepContext(Struct, frozen=True, eq=False):
    """Everything the terms of one time step need beyond the positions x.

    Built once per step by the simulation; a new one (``msgspec.structs.replace``) is made
    whenever the collision set or the friction lag change. Nothing here is ever written
    to after construction. A field a term does not read may be left out (None)."""

    x_start: np.ndarray | None = None  # (n, 3) xₙ, positions at the start of the step
    # (n, 3) where friction's slip is measured from: the integrator's lag origin (xₙ; x̂
    # for BDF2, solver/integrator.py); None: x_start
    slip_origin: np.ndarray | None = None
    x_tilde: np.ndarray | None = None  # (n, 3) x̃, the prediction (targets on kinematic rows)
    acceleration: np.ndarray | None = None  # (n, 3) gravity + active NBCs, 0 on kinematic
    kinematic: np.ndarray | None = None  # (n,) bool, vertices prescribed during the step
    target: np.ndarray | None = None  # (n, 3) where kinematic vertices must end the step
    dhat: float = 0.0  # barrier activation distance d̂ (m)
    collisions: "Collisions | None" = None  # mesh pairs near x (None: no mesh contact)
    friction: "FrictionLag | None" = None  # normal forces and bases lagged at x_lag
    damping: LaggedDamping | None = None
    plane_origins: np.ndarray | None = None  # (p, 3) where the planes are (moving lines)


class ContactTerm:
    """What the contact terms share (a mixin of their Structs): their pairs come and go
    with x, so their Hessian has no fixed pattern, and they act within the squared
    distance ŝ = d̂² (``s_hat``) of their field ``dhat``."""

    __slots__ = ()
    constant_pattern: ClassVar[bool] = False

    @property
    def s_hat(self) -> float:
        return self.dhat * self.dhat


class Potential(Protocol):
    """A term of the incremental potential (see the module docstring)."""

    name: str
    constant_pattern: bool

    def value(self, x: np.ndarray, ctx: StepContext) -> float: ...

    def gradient(self, x: np.ndarray, ctx: StepContext) -> np.ndarray: ...

    def hessian(self, x: np.ndarray, ctx: StepContext) -> Triplets: ...
