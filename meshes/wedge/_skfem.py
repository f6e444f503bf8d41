"""scikit-fem's tetrahedral mesh, its facets and edges numbered through one integer key each.

scikit-fem builds a mesh's facets and edges lazily, and again on every copy that
``scaled``, ``with_subdomains`` or ``with_boundaries`` makes (fem-3d reads the facets of
three copies and the edges of one), by ``np.unique`` over the columns of the sorted node
indices: a structured view, sorted field by field.  Over one int64 key per entity, with the
same stable sort, the arrays come out the same, in about a fifth of the time (0.04 against
0.2 s for the facets at Phi = 0.82, mesh_size 2: 60k tetrahedra).
"""

from __future__ import annotations

import numpy as np
from skfem import MeshTet

__all__ = ["KeyedMeshTet"]

# Keys of k node indices below n are exact while n^k stays below this.
KEY_LIMIT = 2**62


class KeyedMeshTet(MeshTet):
    """:class:`skfem.MeshTet` whose facets and edges are numbered through integer keys."""

    @staticmethod
    def build_entities(t, indices, sort=True):
        """scikit-fem's ``build_entities``: the entities (columns of node indices, sorted
        when ``sort``) in the order of their sorted node indices, and each element's entity
        numbers; the key of a sorted column is its digits in base n (the nodes' count)."""
        if indices is None:
            return None, None
        indexing = np.hstack(tuple(t[ix] for ix in indices))
        nodes = np.sort(indexing, axis=0)
        n = int(t.max()) + 1 if t.size else 1
        if n ** nodes.shape[0] >= KEY_LIMIT:
            return MeshTet.build_entities(t, indices, sort)
        key = nodes[0].astype(np.int64)
        for row in nodes[1:]:
            key = key * n + row
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        mapping = inverse.reshape((len(indices), t.shape[1]))
        return np.ascontiguousarray((nodes if sort else indexing)[:, first]), mapping
