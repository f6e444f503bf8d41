"""The contact faces as a half-space: the contact CG's preconditioner and its starting point.

The condensed operator C = D^T G K^-1 G^T D of :mod:`.contact` costs a back-substitution per
application.  Its half-space model H (units of C: the faces' (1 - nu^2) / E summed over the
two bodies, lengths in mesh units) costs nothing to apply:

    H[i, j] = gamma / pi  sum_g  integral psi_i(x) psi_j(y) / |x - g y|,

the P1 hats psi of the contact vertices, Boussinesq's response gamma / (pi r) (Johnson 1985,
sec. 3.2), summed over the sector's mirror group g (D6 for the wedge: a load on the sector
stands for its symmetric extension), plus each pillar's Hooke shortening c_k W_k W_k^T.  The
integrals are lumped at the vertices (w_i w_j / |x_i - g x_j|) and, wherever that is poor,
replaced by a three-point rule per triangle: for every pair of face triangles one of whose
vertex pairs lies within the sum of their circumradii, the nine vertex-pair pieces of the
lumped form are swapped for the rule's (a quadrature point with itself counts as a uniform
disk of its weight).  Lumped alone, H is about 2.7 times too compliant for the oscillating
modes of the faces and the CG's preconditioned spectrum spreads over a factor 25 (Phi = 0.82,
mesh_size 2.83); with the near pieces, over a factor 5.4, as with the three-point rule on
every pair (5.0).

The preconditioner is (H_FF)^-1 on the CG's free set F (a float32 Cholesky factorisation of
H_FF whenever F changes).  The CG starts from the solution of the contact problem with H in
place of C (a dense problem, solved by the same CG): its contact set is close to the true one
(1476 of 1544 vertices agree there), which spares most of the iterations that would find it,
each of which clips pressures and costs a second application of C.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from pillar_xval.contact import constrained_cg
from pillar_xval.threads import limited

# The degree-2 rule on a triangle: barycentric coordinates of its three points (rows), each
# of weight a third of the area.
RULE = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
# Rows of the lumped model computed at a time (bounds its temporaries to ROWS x n).
ROWS = 512
# The starting point's tolerance: the CG on C takes it from there.
WARM_TOL = 1e-3
# The tolerance to which the diagonal preconditioner finds the starting point's contact set
# (:meth:`HalfSpaceModel.warm_start`): at Phi = 0.82, mesh_size 1.41, 0.1, 3e-2 and 1e-2 took
# 3, 5 and 12 products with H, then 7, 4 and 3 factorised steps; 0.65, 0.51, 0.50 CPU s.
WARM_FIND_TOL = 3e-2


class HalfSpaceModel:
    """H for the contact faces ``faces`` (:class:`.contact.ContactFaces`), with ``springs``
    (each sector pillar's Hooke compliance per unit sector force, or None) and
    ``compliance`` (the faces' summed (1 - nu^2) / E in the units of the condensed
    operator).  ``precondition(r, free)``, ``inverse_diagonal`` (1 / diag H), ``name`` (what
    the CG's preconditioner is: "half-space", or the diagonal where H could not be
    factorised) and :meth:`warm_start`."""

    def __init__(self, faces, springs, compliance: float, sector_angle: float):
        self.faces = faces
        H = half_space_compliance(faces.vertex_points, faces.weights, faces.triangles,
                                  compliance, sector_angle)
        pillar = faces.pillar_of_vertex
        if springs is not None:  # (the floor's vertices, pillar -1, have none)
            for k, c in enumerate(springs):  # the Hooke term c_k W_k W_k^T of each pillar
                idx = np.nonzero(pillar == k)[0]
                H[np.ix_(idx, idx)] += c * np.outer(faces.weights[idx], faces.weights[idx])
        self.inverse_diagonal = 1.0 / np.diag(H).copy()
        self.H = H
        self.factorisations = 0
        # H is factorised on the free sets the iterations ask for, never on all the
        # vertices (that factorisation, of the largest set, was the model's costliest:
        # 0.3 of 1.0 s at Phi = 0.82, mesh_size 2, 2,813 vertices); the first that is not
        # positive definite turns the preconditioner to the diagonal.  The factors are
        # float32: a preconditioner needs no more digits (the CG's iterations were the same,
        # 19 and 14 at Phi = 0.82 and 0.2, mesh_size 2.83 and 2), and LAPACK's float32
        # Cholesky took 0.53 against 0.84 CPU s for the 20 factorisations at Phi = 0.82,
        # mesh_size 2 (load 5-6).
        self._free, self._factor = None, None
        self.name = "half-space"

    def _factorise(self, free) -> bool:
        """H_FF's Cholesky factor on the free set ``free``; False (and the diagonal from
        then on) where it is not positive definite."""
        idx = np.nonzero(free)[0]
        try:
            self._factor = (idx, cho_factor(self.H[np.ix_(idx, idx)].astype(np.float32),
                                            lower=True, check_finite=False))
        except np.linalg.LinAlgError:
            self._factor = None
            self.name = "diagonal (the half-space model was not positive definite)"
            return False
        self._free = free.copy()
        self.factorisations += 1
        return True

    def precondition(self, r, free):
        """(H_FF)^-1 r_F on the free set F, zero outside (H_FF factorised when F changes;
        the diagonal where H is not definite)."""
        if self.name != "half-space" or (not np.array_equal(free, self._free)
                                         and not self._factorise(free)):
            return free * r * self.inverse_diagonal
        idx, factor = self._factor
        z = np.zeros_like(r)
        z[idx] = cho_solve(factor, r[idx].astype(np.float32), check_finite=False)
        return z

    def warm_start(self, b, scale: float) -> np.ndarray:
        """The solution of gap = H p + b, p >= 0, gap >= 0, p gap = 0 (the contact problem
        with the model in place of C), to :data:`WARM_TOL`; zero where H is not definite.

        From p = 0 every interpenetrating vertex is free at first, most of them wrongly
        (4258 of 4699 at Phi = 0.82, mesh_size 1.41, against 1916 at the end), and each
        clipping step shrank the set by a new factorisation: the diagonal preconditioner
        finds the set first (:data:`WARM_FIND_TOL`, a few products with H), then H_FF's
        factors finish.  There the start took 0.50 against 1.44 CPU s, 14 against 20
        factorisations with the CG's; on the lattice study's six levels the CG on C took the
        same iterations, and the same back-substitutions but at Phi = 0.82, mesh_size 2.83
        (35 against 34); sigma0 moved by up to 4.3e-8 (the CG's tolerance)."""
        H = self.H
        apply = lambda p: H @ p  # noqa: E731
        found = constrained_cg(apply, b, np.zeros(len(b)), scale=scale, tol=WARM_FIND_TOL,
                               max_iterations=1000, inverse_diagonal=self.inverse_diagonal,
                               weights=self.faces.weights)
        sol = constrained_cg(apply, b, found.pressure, scale=scale, tol=WARM_TOL,
                             max_iterations=1000, precondition=self.precondition,
                             weights=self.faces.weights)
        return sol.pressure if self.name == "half-space" else np.zeros(len(b))


def serial_dense_algebra():
    """A context in which the model's dense algebra runs on one thread (through
    :func:`pillar_xval.threads.limited`; PARDISO holds its own count inside it for each of its
    calls).  Its factorisations and solves are of a few thousand unknowns at most, where two
    threads cost more than they gain (a Cholesky factorisation at n = 381, 1544 and 4700 took
    0.11, 0.14-0.24 and 1.7-2.4 CPU s on two threads against 0.001-0.005, 0.05 and 0.9-1.0
    on one, on a 2-core machine under a load average of 7-9)."""
    return limited(1)


def half_space_compliance(vertex_points, weights, triangles, compliance: float,
                          sector_angle: float) -> np.ndarray:
    """H without the pillars' Hooke terms (module docstring), dense n x n.

    Parameters
    ----------
    vertex_points : ndarray, shape (2, n)
        Contact vertices (mesh units).
    weights : ndarray, shape (n,)
        w_i, the integral of the hat psi_i.
    triangles : ndarray, shape (3, m)
        The face triangles' vertices (indices into the n).
    compliance : float
        gamma, the faces' summed (1 - nu^2) / E.
    sector_angle : float
        The sector's angle (its mirror group's).
    """
    x = np.asarray(vertex_points, dtype=float).T
    w = np.asarray(weights, dtype=float)
    n = len(w)
    tol = 1e-9 * max(1.0, float(np.max(np.abs(x))) if n else 1.0)
    group = mirror_group(sector_angle)
    S = np.zeros((n, n))
    merged = np.zeros(n)  # images of each vertex that fall on it (itself, its mirrors)
    images = [x @ g.T for g in group]
    # The sum over the group is symmetric (the group holds each g's inverse): the blocks on
    # and above the diagonal are computed, those below copied from them.  A pair within
    # tol under g is one under g's inverse the other way round: the rows' counts, and the
    # columns' beyond the diagonal block.
    for lo in range(0, n, ROWS):
        hi = min(lo + ROWS, n)
        for gx in images:
            d = cdist(x[lo:hi], gx[lo:])
            same = d <= tol
            merged[lo:hi] += same.sum(axis=1)
            merged[hi:] += same[:, hi - lo:].sum(axis=0)
            d[same] = np.inf
            np.reciprocal(d, out=d)
            S[lo:hi, lo:] += d
        S[lo:hi, :lo] = S[:lo, lo:hi].T
    S *= w[:, None]
    S *= w[None, :]
    # A vertex's coinciding images join its hat: a uniform disk of the whole hat's area
    # m_i w_i deflects by 16 gamma rho / (3 pi) on average, rho = sqrt(m_i w_i / pi).
    own = 16.0 / (3.0 * math.pi) * w * np.sqrt(merged * w / math.pi)
    S[np.diag_indices(n)] += own
    if n and np.size(triangles):
        pieces, where = _near_pieces(x, w, np.asarray(triangles), group, tol, own, merged)
        S += np.bincount(where, weights=pieces, minlength=n * n).reshape(n, n)
        S = 0.5 * (S + S.T)
    S *= compliance / math.pi
    return S


def _near_pieces(x, w, tri, group, tol, own, merged):
    """The corrections (rule minus lumped) of the vertex-pair pieces of every near pair of
    face triangles under every g, and their flat indices i n + j."""
    n = len(w)
    P = x[tri]  # (3, m, 2)
    area = 0.5 * np.abs((P[1, :, 0] - P[0, :, 0]) * (P[2, :, 1] - P[0, :, 1])
                        - (P[2, :, 0] - P[0, :, 0]) * (P[1, :, 1] - P[0, :, 1]))
    a = area / 3.0  # the weight of each of a triangle's points, and the integral of its hats
    points = np.einsum("qk,ktd->tqd", RULE, P)
    centre = P.mean(axis=0)
    radius = np.sqrt(np.max(np.sum((P - centre[None]) ** 2, axis=2), axis=0))
    # a point with itself: (1 / a^2) x the integral of 1 / r over a disk of area a, twice
    itself = 16.0 / (3.0 * math.pi) * np.sqrt(a / math.pi) / a
    tree = cKDTree(centre)
    out, where = [], []
    for g in group:
        gx = x @ g.T
        t1, t2 = _candidate_pairs(tree, cKDTree(centre @ g.T), radius)
        vi, vj = tri[:, t1].T[:, :, None], tri[:, t2].T[:, None, :]  # (p, 3, 1), (p, 1, 3)
        dv = np.hypot(x[vi, 0] - gx[vj, 0], x[vi, 1] - gx[vj, 1])  # (p, 3, 3)
        near = dv.min(axis=(1, 2)) <= radius[t1] + radius[t2]
        t1, t2, vi, vj, dv = t1[near], t2[near], vi[near], vj[near], dv[near]
        if not len(t1):
            continue
        q2 = points[t2] @ g.T
        dist = np.sqrt(np.sum((points[t1][:, :, None, :] - q2[:, None, :, :]) ** 2, axis=3))
        same = dist <= tol
        with np.errstate(divide="ignore"):
            kernel = 1.0 / dist
        kernel[same] = np.broadcast_to(itself[t1][:, None, None], kernel.shape)[same]
        piece = (a[t1] * a[t2])[:, None, None]
        rule = np.einsum("qk,pqr,rl->pkl", RULE, kernel, RULE) * piece
        vi, vj = np.broadcast_to(vi, dv.shape), np.broadcast_to(vj, dv.shape)
        coincide = dv <= tol
        with np.errstate(divide="ignore"):
            lumped = piece / dv
        # the lumped form's own term of a vertex, shared out over its pieces and images
        shared = own[vi] * piece / (w[vi] ** 2 * merged[vi])
        lumped[coincide] = shared[coincide]
        out.append((rule - lumped).ravel())
        where.append((vi * n + vj).ravel())
    if not out:
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    return np.concatenate(out), np.concatenate(where)


def _candidate_pairs(tree, image_tree, radius):
    """Pairs (t1, t2) of triangles, the second's image under a mirror-group element, whose
    centres lie within 4 max(r1, r2) (circumradii r): all that can be near (a vertex pair
    within r1 + r2 puts the centres within 2 (r1 + r2)), each found from its larger
    triangle.  A reach of 4 max(r) over all triangles instead made the pairs, their memory
    and time grow with the largest triangle, one far from the rest on a graded floor."""
    def within(a, b, keep):  # the points of tree b within 4 r of each point of tree a
        found = b.query_ball_point(a.data, 4.0 * radius)
        i = np.repeat(np.arange(len(found)), [len(f) for f in found])
        j = np.fromiter(itertools.chain.from_iterable(found), dtype=np.int64, count=len(i))
        sel = keep(radius[i], radius[j])
        return i[sel], j[sel]

    i1, j1 = within(tree, image_tree, np.greater_equal)  # t2 no larger than t1
    j2, i2 = within(image_tree, tree, np.greater)  # t1 smaller than t2
    t1, t2 = np.concatenate([i1, i2]), np.concatenate([j1, j2])
    order = np.lexsort((t2, t1))
    return t1[order], t2[order]


def mirror_group(sector_angle: float) -> list:
    """The 2 x 2 matrices of the group generated by the mirrors theta = 0 and theta =
    ``sector_angle`` (pi / sector_angle rotations by multiples of twice the angle, and as many
    reflections): 12 for the D6 wedge."""
    k = int(round(math.pi / sector_angle))
    out = []
    for j in range(k):
        c, s = math.cos(2 * j * sector_angle), math.sin(2 * j * sector_angle)
        rotation = np.array([[c, -s], [s, c]])
        out += [rotation, rotation @ np.diag([1.0, -1.0])]
    return out
