"""The reduced stiffness T^T A T of the sector model, written from A's node-pair blocks.

The transform T (:func:`.system._transform`) maps each P2 node's three displacement
components to reduced unknowns of that node alone: u = Q t with Q the identity for most
nodes, an orthonormal basis of 2 or 1 columns on the mirror planes and the far faces, none
where clamped.  The reduced block of a node pair (s, t) is then Q_s^T A_st Q_t, at the
nodes' own reduced rows and columns, and K_uu is A's pattern of node pairs with a mask of
the kept components.  Writing it from the blocks spares scipy's block-to-CSR copy of A and
the two sparse products: at Phi = 0.82, mesh_size 1.41 on paper-fig3-sparse their 0.74 s
of user time, and A, A T_u and K_uu, 0.7 GB each of fresh pages, whose first touch cost
1-2.5 s of system time on one core (the matrix is written where the factorised matrix
holds it: no copy of its own).

The sums are those of the products, in their order: the entries are the same bits
(tested); a rigid pillar's base nodes share its motion columns, and keep the products.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

# Node pairs per pass of :meth:`ReducedStiffness.write`: its index arrays hold three entries each.
PAIRS = 1 << 16
# The slots past a matrix's entries that :meth:`ReducedStiffness.write` needs: three entries'
# items written to the first of them.
SPARE = 3


@dataclass
class NodeBases:
    """The reduced unknowns of each P2 node under T.

    ``first[s]``: the node's first reduced column (its columns are consecutive),
    ``count[s]``: how many (0 where clamped; -1 where a rigid pillar carries it),
    ``kind[s]``: its basis, ``bases[kind]`` (3 x 3): Q with zero columns past ``count``.
    """

    first: np.ndarray
    count: np.ndarray
    kind: np.ndarray
    bases: np.ndarray

    @property
    def order(self) -> np.ndarray:
        """Each basis's columns (kinds x 3) in the order scipy's product T_u^T (A T_u) lays
        out a node's columns in a row: by their first nonzero component (the zero columns
        last)."""
        lead = np.argmax(self.bases != 0.0, axis=1)
        lead[~np.any(self.bases != 0.0, axis=1)] = 3
        return np.argsort(lead, axis=1, kind="stable")

    @property
    def direct(self) -> bool:
        """Every node's unknowns are its own (no rigid pillar): :class:`ReducedStiffness`
        applies."""
        return bool(np.all(self.count >= 0))


class ReducedStiffness:
    """K_uu = T_u^T A T_u (n_reduced x n_reduced) from A's 3 x 3 blocks ``blocks[k]`` (row
    component b, column component a) at the node pairs (row[k], col[k]), sorted by row then
    column (``blocks`` is overwritten with the reduced blocks): its row ``lengths``, and its
    entries written where the caller places its rows (:meth:`write`, :func:`.system.stack_csr`),
    or as a CSR matrix (:meth:`tocsr`).

    The arrays of scipy's product T_u^T (A T_u) bit for bit, in its order: the column nodes
    ascending, a node's columns in :attr:`NodeBases.order`, the entries the product meets
    late first (:meth:`_reorder_mixed`).  Exact zeros, which the product leaves out, are
    written (the caller's ``eliminate_zeros`` drops them)."""

    dtype = np.dtype(float)

    def __init__(self, row: np.ndarray, col: np.ndarray, blocks: np.ndarray,
                 nodes: NodeBases, n_reduced: int):
        first, count = nodes.first, nodes.count
        self.order = nodes.order
        # the pairs whose row node mixes components in a column (the skew mirror), and where
        # the product first meets each of their entries (below)
        self.mixed, self.meets = _transform_blocks(row, col, blocks, nodes, self.order)
        self.row, self.col, self.blocks, self.nodes = row, col, blocks, nodes
        self.shape = (n_reduced, n_reduced)
        self.width = count[col]  # each pair's entries in a row
        self.before = np.zeros(len(col) + 1, dtype=np.int64)  # the entries before each pair
        np.cumsum(self.width, out=self.before[1:])
        N = len(first)
        self.ptr = np.searchsorted(row, np.arange(N + 1))
        length = self.before[self.ptr[1:]] - self.before[self.ptr[:-1]]  # a node's rows'
        owner = np.repeat(np.arange(N), count)  # the node of each reduced row, in node order
        rank = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
        self.lengths = np.zeros(n_reduced, dtype=np.int64)
        self.lengths[first[owner] + rank] = length[owner]

    def write(self, data: np.ndarray, indices: np.ndarray, start: np.ndarray,
              shift: int = 0) -> None:
        """Row r's entries into ``data[start[r]:start[r] + lengths[r]]``, their columns plus
        ``shift`` into ``indices``; both arrays hold :data:`SPARE` slots past the matrix's
        entries, which take the writes of the rows a node does not keep."""
        dump = len(data) - SPARE
        rows = self._node_rows(start, shift, indices.dtype, dump)
        # A pair's three entries in one of its rows, one item each: an item is copied whole
        # (a third of the index work of one entry at a time: 0.18 against 1.1-1.3 s for
        # 5.8e7 entries)
        data3, indices3 = _triples(data), _triples(indices)
        for lo in range(0, len(self.row), PAIRS):
            pairs = slice(lo, min(lo + PAIRS, len(self.row)))
            at, columns = self._rows(pairs, rows, dump)
            at[self.width[pairs] < 3] = dump  # their entries one at a time below
            data3[at] = _items(self.blocks[pairs]).reshape(at.shape)
            indices3[at] = _items(columns)[:, None]
        # the pairs whose column node keeps fewer components
        partial = np.nonzero(self.width < 3)[0]
        for lo in range(0, len(partial), PAIRS):
            pairs = partial[lo:lo + PAIRS]
            at, columns = self._rows(pairs, rows, dump)
            at = self._entries(pairs, at, dump)
            data[at] = self.blocks[pairs]
            indices[at] = columns[:, None, :]
        self._reorder_mixed(data, indices, rows, dump)

    def _reorder_mixed(self, data, indices, rows, dump: int) -> None:
        """The rows of a node whose basis column mixes components (b_0 < b_1 < ...): the
        product meets an entry at the first b whose (A Q) term is not an exact zero, and lays
        out the entries met at a later b first, the latest first (each group in the order of
        the others)."""
        if not len(self.mixed):
            return
        at = self._entries(self.mixed, self._rows(self.mixed, rows, dump)[0], dump).ravel()
        meets = self.meets.ravel()
        row = np.repeat(self.nodes.first[self.row[self.mixed]][:, None] + np.arange(3), 3,
                        axis=1).ravel()
        keep = at < dump  # a row a node does not keep went to the spare slots
        at, meets, row = at[keep], meets[keep], row[keep]
        new = at[np.lexsort((at, -meets, row))]  # by row, the latest met first, then in place
        slots = np.sort(at)  # the same places, row by row
        data[slots] = data[new]
        indices[slots] = indices[new]

    def _node_rows(self, start: np.ndarray, shift: int, index_dtype, dump: int):
        """Per node: where its rows' entries start, less the entries of the row's pairs
        before the node's first (N, 3; at least ``dump`` for the rows it does not keep),
        and its columns plus ``shift`` in :attr:`order` (N, 3)."""
        first, count = self.nodes.first, self.nodes.count
        three = np.arange(3)
        base = start[np.minimum(first[:, None] + three, self.shape[0] - 1)]
        base -= self.before[self.ptr[:-1]][:, None]
        base[three >= count[:, None]] = dump
        columns = (first + shift)[:, None] + self.order[self.nodes.kind]
        return base, columns.astype(index_dtype)

    def _rows(self, pairs, rows, dump: int):
        """Of the pairs ``pairs`` (a slice or indices): where each of their rows' entries
        start (n, 3; ``dump`` for the rows a node does not keep), and their columns (n, 3)."""
        base, columns = rows
        at = base[self.row[pairs]] + self.before[pairs][:, None]
        return np.minimum(at, dump, out=at), columns[self.col[pairs]]

    def _entries(self, pairs, at: np.ndarray, dump: int) -> np.ndarray:
        """Each entry's place (n, 3, 3) from its row's (``at``), ``dump`` for the components
        the column node does not keep."""
        kept = (np.arange(3) < self.width[pairs, None])[:, None, :]
        return np.where(kept, at[:, :, None] + np.arange(3), dump)

    def tocsr(self) -> sp.csr_matrix:
        """The matrix alone, as CSR (exact zeros in)."""
        indptr = np.zeros(self.shape[0] + 1, dtype=np.int64)
        np.cumsum(self.lengths, out=indptr[1:])
        index_dtype = np.int32 if max(indptr[-1], self.shape[1]) < 2**31 else np.int64
        data = np.empty(int(indptr[-1]) + SPARE)
        indices = np.empty(len(data), dtype=index_dtype)
        self.write(data, indices, indptr[:-1])
        K = sp.csr_matrix((data[:-SPARE], indices[:-SPARE], indptr.astype(index_dtype)),
                          shape=self.shape)
        return K


def _triples(a: np.ndarray) -> np.ndarray:
    """The 1-D array ``a`` seen as overlapping items of three entries: item p is a[p:p + 3]."""
    return np.ndarray((len(a) - 2,), dtype=np.dtype((np.void, 3 * a.itemsize)), buffer=a,
                      strides=(a.itemsize,))


def _items(a: np.ndarray) -> np.ndarray:
    """The last axis (three entries) of ``a`` as one item: shape a.shape[:-1]."""
    a = np.ascontiguousarray(a)
    return a.view(np.dtype((np.void, 3 * a.itemsize))).reshape(a.shape[:-1])


def _transform_blocks(row, col, blocks, nodes: NodeBases, order: np.ndarray):
    """Q_s^T A_st Q_t in place for the pairs that touch a node whose basis is not the
    identity, its columns in ``order`` (kinds x 3), summed as scipy's products sum them:
    (A Q)[b, j] over the components c in turn, then Q^T (A Q)[j', j] over b in turn (a
    zero of Q adds a signed zero: the same sum).

    Returns the pairs whose row node's basis mixes components in a column, and for each of
    their entries [j', i] how many of that column's nonzero components come before the one
    where the product first meets it (n, 3, 3)."""
    identity = np.array([np.array_equal(Q, np.eye(3)) for Q in nodes.bases])
    plain = identity[nodes.kind] | (nodes.count == 0)  # clamped nodes are masked, not mixed
    pairs = np.nonzero(~(plain[row] & plain[col]))[0]
    ordered = np.take_along_axis(nodes.bases, order[:, None, :], axis=2)
    mixing = np.any(np.sum(nodes.bases != 0.0, axis=1) > 1, axis=1)  # per kind
    mixed, meets = [], []
    for lo in range(0, len(pairs), PAIRS):
        k = pairs[lo:lo + PAIRS]
        A = blocks[k]
        Qs, Qt = nodes.bases[nodes.kind[row[k]]], ordered[nodes.kind[col[k]]]
        AQ = A[:, :, 0, None] * Qt[:, None, 0, :]
        for c in (1, 2):
            AQ = AQ + A[:, :, c, None] * Qt[:, None, c, :]
        R = Qs[:, 0, :, None] * AQ[:, 0, None, :]
        for b in (1, 2):
            R = R + Qs[:, b, :, None] * AQ[:, b, None, :]
        blocks[k] = R
        m = mixing[nodes.kind[row[k]]]
        if m.any():
            # b of row j' where the product first meets entry i: the first b with
            # Q_s[b, j'] and (A Q)[b, i] both nonzero; counted among Q_s[:, j']'s nonzeros
            nz = Qs[m] != 0.0  # (n, b, j')
            hit = nz[:, :, :, None] & (AQ[m] != 0.0)[:, :, None, :]  # (n, b, j', i)
            first_b = np.argmax(hit, axis=1)  # (n, j', i)
            earlier = np.cumsum(nz, axis=1) - nz  # nonzeros of Q_s[:, j'] before b
            meets.append(np.take_along_axis(earlier[:, :, :, None], first_b[:, None],
                                            axis=1)[:, 0])
            mixed.append(k[m])
    if not mixed:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3, 3), dtype=np.int64)
    return np.concatenate(mixed), np.concatenate(meets)
