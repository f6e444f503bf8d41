"""Dense influence operators: element forces (N) -> normal displacements (m).

The full operator over all elements is

    K[a, b] = (gamma_l + gamma_s) / pi * D(x_a; square_b) / area_b + c_h [pillar(a) == pillar(b)],

Love's coefficient D per unit force plus the Hooke shortening c_h = 4 h / (pi d^2 E_p) of a
pillar under the force of each of its elements (a low-rank term).  Collocation with Love's
formula is symmetric only up to O((b/r)^4) between squares of different orientation, so the
solvers use the symmetric part (K + K^T)/2: the energy of the discrete problem, with an
operator change far below the discretisation error.

With pressures constant on symmetry orbits (expansion E from representatives to images), the
reduced operator is M = E^T K E, computed without forming K: for a representative row i,
(E^T K E)[i, j] = |orbit(i)| * sum over the images b of j of K(x_i, b), by invariance of the
discretisation under the orbit group; the block (off-centre row, centre column) uses the
images of the row instead, because rotations by pi/3 do not map the centre grid onto itself.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from scenes import Scene

from ._discretise import Discretisation
from ._love import unit_force_influence

# Entries evaluated per block: temporaries of ~2 MB stay in cache.
_BLOCK = 250_000
_THREADS = 2


def _coefficients(scene: Scene) -> tuple[float, float]:
    return scene.half_space_compliance / math.pi, scene.pillar_spring_compliance


def _influence(px, py, disc: Discretisation, cols: slice | np.ndarray, scale: float):
    """gamma/pi * D / area: displacement at points (px, py) per unit force on image columns."""
    # Loaded squares have area side^2 (covered cells use an equivalent square).
    return scale * unit_force_influence(
        px[:, None], py[:, None], disc.img_x[cols][None, :], disc.img_y[cols][None, :],
        disc.img_angle[cols][None, :], disc.img_side[cols][None, :])


def _row_sums(scene: Scene, disc: Discretisation) -> np.ndarray:
    """R[i, j] = sum over images b of rep j of K_love(x_i, b): the displacement at rep i per
    unit force on every image of rep j (Love part only)."""
    scale, _ = _coefficients(scene)
    n = disc.n_unknowns
    R = np.empty((n, n))
    start = disc.rep_start
    reps_per_block = max(1, int(_BLOCK / max(n, 1) / max(np.mean(np.diff(start)), 1.0)))
    blocks = [(j0, min(n, j0 + reps_per_block)) for j0 in range(0, n, reps_per_block)]

    def work(block):
        j0, j1 = block
        cols = slice(start[j0], start[j1])
        k = _influence(disc.rep_x, disc.rep_y, disc, cols, scale)
        R[:, j0:j1] = np.add.reduceat(k, start[j0:j1] - start[j0], axis=1)

    with ThreadPoolExecutor(_THREADS) as pool:
        list(pool.map(work, blocks))
    return R


def reduced_operator(scene: Scene, disc: Discretisation) -> np.ndarray:
    """Symmetric reduced operator M = sym(E^T K E) over the representatives (m/N, weighted)."""
    scale, c_h = _coefficients(scene)
    w = disc.rep_weight.astype(float)
    M = _row_sums(scene, disc)
    if c_h > 0.0 and len(disc.orbit_size):
        # Images of rep j on the pillar of rep i: only when both lie on the same pillar orbit,
        # then w_j / (pillars in that orbit) of them.
        same = disc.rep_orbit[:, None] == disc.rep_orbit[None, :]
        per_pillar = w / disc.orbit_size[disc.rep_orbit]
        M += c_h * same * per_pillar[None, :]
    M *= w[:, None]

    centre = np.nonzero(disc.rep_centre)[0]
    other = np.nonzero(~disc.rep_centre)[0]
    if len(centre) and len(other):
        # (off-centre row i, centre column j): sum over the images a of i of the displacement
        # at a due to the centre images of j.
        img_other = np.nonzero(~disc.rep_centre[disc.img_rep])[0]
        cen_cols = np.nonzero(disc.rep_centre[disc.img_rep])[0]
        k = _influence(disc.img_x[img_other], disc.img_y[img_other], disc, cen_cols, scale)
        # Squares are centred on their collocation points, so image positions serve as both.
        block = np.zeros((disc.n_unknowns, len(cen_cols)))
        np.add.at(block, disc.img_rep[img_other], k)
        to_rep = np.zeros((len(cen_cols), disc.n_unknowns))
        to_rep[np.arange(len(cen_cols)), disc.img_rep[cen_cols]] = 1.0
        M[np.ix_(other, centre)] = (block @ to_rep)[np.ix_(other, centre)]
    return 0.5 * (M + M.T)


def full_operator(scene: Scene, disc: Discretisation) -> np.ndarray:
    """Symmetric operator over every image element, sym(K) (m/N): the unreduced system."""
    scale, c_h = _coefficients(scene)
    allcols = np.arange(disc.n_elements)
    K = _influence(disc.img_x, disc.img_y, disc, allcols, scale)
    if c_h > 0.0:
        K += c_h * (disc.img_pillar[:, None] == disc.img_pillar[None, :])
    return 0.5 * (K + K.T)


def expansion(disc: Discretisation) -> np.ndarray:
    """E (n_elements x n_unknowns): 1 where an image belongs to a representative."""
    E = np.zeros((disc.n_elements, disc.n_unknowns))
    E[np.arange(disc.n_elements), disc.img_rep] = 1.0
    return E
