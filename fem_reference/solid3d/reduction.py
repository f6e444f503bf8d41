"""The reduced stiffness T^T A T of the sector model, written from A's node-pair blocks.

The transform T (:func:`.system._transform`) maps each P2 node's three displacement
components to reduced unknowns of that node alone: u = Q t with Q the identity for most
nodes, an orthonormal basis of 2 or 1 columns on the mirror planes and the far faces, none
where clamped.  The reduced block of a node pair (s, t) is then Q_s^T A_st Q_t, at the
nodes' own reduced rows and columns, and K_uu is A's pattern of node pairs with a mask of
the kept components.  Writing it from the blocks spares scipy's block-to-CSR copy of A and
the two sparse products (at Phi = 0.82, mesh_size 1.41 on paper-fig3-sparse: 1.2 s and
2.0 s of CPU time, and A and A T, 0.7 GB each, alive at once).

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

    The entries of scipy's product T_u^T (A T_u) bit for bit, each row's columns sorted,
    exact zeros left in (the product drops them; ``eliminate_zeros`` does)."""

    dtype = np.dtype(float)

    def __init__(self, row: np.ndarray, col: np.ndarray, blocks: np.ndarray,
                 nodes: NodeBases, n_reduced: int):
        first, count = nodes.first, nodes.count
        _transform_blocks(row, col, blocks, nodes)
        self.row, self.col, self.blocks, self.nodes = row, col, blocks, nodes
        self.shape = (n_reduced, n_reduced)
        # Each row's pairs in the order of their columns' reduced unknowns: T numbers them
        # kind by kind (the bases are listed in that order), each kind's nodes ascending.
        self.sequence = np.argsort(row * len(nodes.bases) + nodes.kind[col], kind="stable")
        self.width = count[col[self.sequence]]  # each pair's entries in a row
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
        column = (self.nodes.first + shift).astype(indices.dtype)
        # A pair's three entries in one of its rows, one item each: an item is copied whole
        # (a third of the index work of one entry at a time: 0.18 against 1.1-1.3 s for
        # 5.8e7 entries)
        data3, indices3 = _triples(data), _triples(indices)
        for lo in range(0, len(self.row), PAIRS):
            pairs = slice(lo, min(lo + PAIRS, len(self.row)))
            at, values, columns = self._rows(pairs, start, column, dump)
            at[self.width[pairs] < 3] = dump  # their entries one at a time below
            data3[at] = _items(values).reshape(at.shape)
            indices3[at] = _items(columns)[:, None]
        # the pairs whose column node keeps fewer components
        partial = np.nonzero(self.width < 3)[0]
        for lo in range(0, len(partial), PAIRS):
            pairs = partial[lo:lo + PAIRS]
            at, values, columns = self._rows(pairs, start, column, dump)
            kept = (np.arange(3) < self.width[pairs, None])[:, None, :]
            at = np.where(kept, at[:, :, None] + np.arange(3), dump)
            data[at] = values
            indices[at] = columns[:, None, :]

    def _rows(self, pairs: np.ndarray, start: np.ndarray, column: np.ndarray, dump: int):
        """Of the pairs ``pairs`` (a slice or indices) in the sequence: where each of their rows' entries
        start (n, 3; ``dump`` for the rows a node does not keep), their blocks (n, 3, 3) and
        their columns (n, 3)."""
        first, count = self.nodes.first, self.nodes.count
        three = np.arange(3)
        k = self.sequence[pairs]
        s, t = self.row[pairs], self.col[k]  # the sequence keeps the rows
        # a row's start, past the row's pairs before this one
        at = start[np.minimum(first[s][:, None] + three, self.shape[0] - 1)]
        at += (self.before[pairs] - self.before[self.ptr[s]])[:, None]
        at[three >= count[s][:, None]] = dump
        return at, self.blocks[k], column[t][:, None] + three.astype(column.dtype)

    def tocsr(self) -> sp.csr_matrix:
        indptr = np.zeros(self.shape[0] + 1, dtype=np.int64)
        np.cumsum(self.lengths, out=indptr[1:])
        index_dtype = np.int32 if max(indptr[-1], self.shape[1]) < 2**31 else np.int64
        data = np.empty(int(indptr[-1]) + SPARE)
        indices = np.empty(len(data), dtype=index_dtype)
        self.write(data, indices, indptr[:-1])
        K = sp.csr_matrix((data[:-SPARE], indices[:-SPARE], indptr.astype(index_dtype)),
                          shape=self.shape)
        K.has_sorted_indices = True
        return K


def _triples(a: np.ndarray) -> np.ndarray:
    """The 1-D array ``a`` seen as overlapping items of three entries: item p is a[p:p + 3]."""
    return np.ndarray((len(a) - 2,), dtype=np.dtype((np.void, 3 * a.itemsize)), buffer=a,
                      strides=(a.itemsize,))


def _items(a: np.ndarray) -> np.ndarray:
    """The last axis (three entries) of ``a`` as one item: shape a.shape[:-1]."""
    a = np.ascontiguousarray(a)
    return a.view(np.dtype((np.void, 3 * a.itemsize))).reshape(a.shape[:-1])


def _transform_blocks(row, col, blocks, nodes: NodeBases) -> None:
    """Q_s^T A_st Q_t in place for the pairs that touch a node whose basis is not the
    identity, summed as scipy's products sum them: (A Q)[b, j] over the components c in
    turn, then Q^T (A Q)[j', j] over b in turn (a zero of Q adds a signed zero: the same
    sum)."""
    identity = np.array([np.array_equal(Q, np.eye(3)) for Q in nodes.bases])
    plain = identity[nodes.kind] | (nodes.count == 0)  # clamped nodes are masked, not mixed
    pairs = np.nonzero(~(plain[row] & plain[col]))[0]
    for lo in range(0, len(pairs), PAIRS):
        k = pairs[lo:lo + PAIRS]
        A = blocks[k]
        Qs, Qt = nodes.bases[nodes.kind[row[k]]], nodes.bases[nodes.kind[col[k]]]
        AQ = A[:, :, 0, None] * Qt[:, None, 0, :]
        for c in (1, 2):
            AQ = AQ + A[:, :, c, None] * Qt[:, None, c, :]
        R = Qs[:, 0, :, None] * AQ[:, 0, None, :]
        for b in (1, 2):
            R = R + Qs[:, b, :, None] * AQ[:, b, None, :]
        blocks[k] = R
