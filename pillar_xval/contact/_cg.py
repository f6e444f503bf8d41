"""Constrained conjugate gradients for the discrete contact problem (Polonsky and Keer).

Solves, for a symmetric positive definite compliance operator A (m/Pa), the linear
complementarity problem of displacement-controlled frictionless contact

    gap = A q + b,   q >= 0,   gap >= 0,   q_i gap_i = 0  for every cell i,

with b = g - zeta the undeformed gap minus the indentation (m) and q the cell pressures (Pa).
This is the minimisation of 1/2 q.A q + b.q over q >= 0.  Under force control (``force``)
the approach is one more unknown, the multiplier of the force's constraint, found as Polonsky
and Keer do, by the mean-gap shift of their step 3 (:class:`_ForceControl`).

Free set.  The conjugate directions live on the *free set*: the contact set {q > 0} and the
cells out of contact that interpenetrate (gap < 0).  An interpenetrating cell thus enters the
contact through the same preconditioned direction and the same exact line search as the
cells in contact, and a step that drives pressures negative is truncated at zero (Vollebregt's
bound-constrained CG).  Polonsky and Keer instead give entering cells a separate
steepest-descent step tau D^-1 gap, each as if it were alone: on pillars much softer than the
substrate, where a pillar's cells share a Hooke compliance up to 1e3 times a cell's own, a
ring of cells entering together so overloads the pillar (x 170 its force in one step, measured)
that the iteration never recovers (3,800 iterations on paper-fig3-sparse with Phi = 0.1,
E_s = 10 E_p).  Through the preconditioner the entering cells see the Hooke term.

Conjugacy.  beta is Polak-Ribiere's, floored at zero (PR+): it restarts itself when the free
set changes what the previous direction meant, where Fletcher-Reeves' beta kept stale
directions after large changes of the contact set.  The direction is also restarted when it
no longer descends.

The directions may be preconditioned by an operator ``precondition(r, free)`` that is SPD on
the free set: :func:`diagonal_preconditioner` scales by the diagonal (which varies on partly
covered edge cells) and carries the Hooke term of soft pillars, whose uniform mode is up to
1e4 times more compliant than the half-space modes at E_p / E_l = 1e-4.

Energy.  Truncating a step at zero can raise the energy 1/2 q.A q + b.q that the iteration
minimises.  On most problems that does no harm (steps that raise it come and go on pillars
100-1000 times softer than the lens on the sparse scene, which converge in 15-22 iterations
all the same), but on soft pillars in a dense lattice the iteration can cycle.  With
E_p = 1e-3 E_l at Phi = 0.9 under a lens of R = 0.1 m, one truncated step raised the energy
from -3.7e-5 to +0.19 Pa m; hundreds of cells then left and re-entered the contact at every
step, and the residual never again reached its best value.  paper-fig3-dense itself with
E_p = 1e-3 E_l did not converge in 7,500 iterations.
So once the residual has not improved on its best for ``STALL_ITERATIONS`` iterations (at
most 13 on every scene measured that converges), the iteration turns monotone: a truncated
step is taken only if it lowers the energy, else its length is halved, with the gap
recomputed exactly, until it does (at most ``BACKTRACK_MAX`` times), and the direction is
restarted (a projected search with backtracking [4]).  A step that is not truncated is an
exact line search and lowers the energy by tau slope / 2.  Until then, nothing changes.

Directions at the bound.  At an entering cell (q_i = 0, gap_i < 0) the preconditioned,
conjugated direction t may still point out of the feasible set (t_i > 0): the step -tau t_i
takes its pressure below zero, to be clipped at once, at the cost of a clipping update of
the gap.  With ``cut_outward`` those components are zeroed, the direction projected onto
the directions that keep q >= 0 there; as gap_i < 0 on them, the cut only raises the slope
gap.t, so the direction still descends and the exact line search runs along it.  In the
FFT model (which cuts), over 24 scenes (rigid, Hooke and soft pillars, with and without the
floor, N = 8-36, both preconditioners), the operator applications were fewer on 16 and as
many on 7: 41 instead of 46 with the floor reached and 27 instead of 29 suspended (rigid
pillars, R = 1 mm, Phi = 0.03, N = 36), 37 instead of 45 on paper-fig3-dense (N = 32);
on the four soft-pillar scenes where the safeguard above had shortened 12-114 steps, none
was shortened and the applications fell 58-85 % (203 to 30 near close packing).  They rose
on one, paper-fig3-dense with E_p = E_l / 1000 at N = 24 (98 against 90; 15 steps
shortened against 7).  fem-3d cuts too (an application is a back-substitution there): on
the lattice study's six levels the same iterations, 1-2 fewer back-substitutions of 28-35
at four (a clipping each), as many at Phi = 0.82, mesh_size 2 and 1.41 (39 and 40).

Mixed precision.  An operator may offer a cheaper, approximate application
(``apply.approximate``, its error within ``apply.approximate_error`` of its result's largest
value: the FFT model's float32 transforms).  The steps then use it, the iteration keeps a
bound on the error this leaves in the recursively updated gap, and recomputes the gap exactly
when that bound reaches ``DRIFT_SHARE`` of the residual and before it accepts a residual
within ``tol`` (the reliable updates of mixed-precision Krylov solvers [3]): the returned
residual is always that of the exact gap.

Stopping: the min-map residual of the complementarity problem,

    e_i = |gap_i| where q_i > 0,   max(-gap_i, 0) where q_i = 0,

in the max norm relative to the indentation, ``error = max_i e_i / zeta <= tol``.  It is zero
exactly at the solution and bounds the interpenetration and the gap on the contact set.

References
----------
.. [1] I. A. Polonsky, L. M. Keer, "A numerical method for solving rough contact problems
   based on the multi-level multi-summation and conjugate gradient techniques", Wear 231
   (1999) 206-219.
.. [2] E. A. H. Vollebregt, "The bound-constrained conjugate gradient method for non-negative
   matrices", J. Optim. Theory Appl. 162 (2014) 931-953 (truncation, Polak-Ribiere
   continuation, preconditioned variant).
.. [3] G. L. G. Sleijpen, H. A. van der Vorst, "Reliable updated residuals in hybrid Bi-CG
   methods", Computing 56 (1996) 141-163 (recomputing the recursive residual when its error
   could matter).
.. [4] D. P. Bertsekas, "On the Goldstein-Levitin-Polyak gradient projection method", IEEE
   Trans. Automat. Control 21 (1976) 174-184 (a projected step shortened until it lowers the
   objective).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

from ._solution import ContactSolution
from ._xp import NUMPY, one_piece


class Operator(Protocol):
    """What :func:`constrained_cg` applies: q (Pa) -> A q (m), A symmetric positive
    definite."""

    def __call__(self, q: Any) -> Any: ...


@runtime_checkable
class FewCellUpdates(Protocol):
    """An operator that updates the gap after a step that clips a few pressures without a
    whole application: A d for d = ``values`` on the cells ``index`` and zero elsewhere, or
    None where a whole application is cheaper (``single``: in the cheap precision of
    :class:`MixedPrecision`)."""

    def apply_few(self, index: Any, values: Any, single: bool = False) -> Any: ...


@runtime_checkable
class MixedPrecision(Protocol):
    """An operator with a cheaper application for the CG's steps (``approximate``, or None
    when there is none) and a bound on its relative error (``approximate_error``)."""

    approximate: Callable[[Any], Any] | None
    approximate_error: float

# The gap is recomputed from q (one more operator application) after this many iterations
# with an unchanged contact set, so the recursively updated gap cannot drift.
REFRESH_EVERY = 50
# With an approximate operator (``apply.approximate``) the recursively updated gap carries
# the steps' rounding; it is recomputed exactly once that error's bound exceeds this share of
# the residual, and always before the residual is accepted.
DRIFT_SHARE = 0.1
# Iterations without a new best residual after which truncated steps must lower the energy
# (module docstring; the longest such run measured on a converging scene was 13), and the
# halvings of a step's length allowed before it is taken anyway (the direction restarted).
STALL_ITERATIONS = 20
BACKTRACK_MAX = 12
METHOD = "constrained-cg"


def diagonal_preconditioner(diagonal, spring=0.0, pillar=None, n_pillars=0, backend=None):
    """Inverse of M = D + c P P^T restricted to the free set (Sherman-Morrison).

    ``diagonal`` is D, the diagonal of the half-space operator (m/Pa; larger on partly
    covered cells, whose force acts on a smaller square); ``spring`` c the Hooke compliance
    per unit cell pressure (m/Pa); P the cell-to-pillar incidence.  For soft pillars (c n >> D,
    n cells per top) the uniform mode of each pillar is many orders more compliant than the
    half-space modes; M carries that mode so the conjugate gradients do not see it.
    ``backend`` is the array backend of the vectors (:mod:`pillar_xval.contact._xp`; default numpy).
    """
    be = NUMPY if backend is None else backend
    xp = be.xp
    inv_d = 1.0 / be.asarray(diagonal, dtype=xp.float64)
    if spring <= 0.0 or pillar is None:
        return lambda r, free: xp.where(free, r * inv_d, 0.0)

    per_pillar = be.segments(pillar, n_pillars)

    def apply(r, free):
        z = xp.where(free, r * inv_d, 0.0)
        weight = per_pillar(xp.where(free, inv_d, 0.0))
        sums = per_pillar(z)
        coef = sums / (1.0 / spring + weight)
        return xp.where(free, z - xp.take(coef, pillar) * inv_d, 0.0)

    return apply


def constrained_cg(apply: Operator, b, q0, *, scale, tol=1e-8, max_iterations=10000, precondition=None,
                   inverse_diagonal=None, weights=None, callback=None,
                   backend=None, force=None, load=None,
                   cut_outward: bool = False) -> ContactSolution:
    """Constrained conjugate gradients on the free set, displacement- or force-controlled.

    Parameters
    ----------
    apply : Operator
        q (Pa) -> A q (m); A symmetric positive definite.  If it is also
        :class:`FewCellUpdates`, a step that clips pressures updates the gap by its
        ``apply_few`` instead of a fresh application.  If it is :class:`MixedPrecision` with a
        callable ``approximate``, the steps use that (mixed precision, see the module
        docstring) and ``apply_few`` is called with ``single=True``.
    b : array
        Undeformed gap minus indentation (m); under force control the undeformed gap alone.
    q0 : array
        Initial pressures (Pa), >= 0 (under force control rescaled to ``force``).
    scale : float
        Length (m) that normalises the residual (the indentation zeta); under force control
        the approach found replaces it as soon as it is positive.
    tol : float
        Stop when max-norm min-map residual / scale <= tol.
    max_iterations : int
        Give up after this many iterations (``converged = False``, never silently).
    precondition : callable, optional
        (r, free) -> z, SPD on the free set and zero outside it.
    inverse_diagonal : array, optional
        1 / diag(A) (Pa/m): the (Jacobi) preconditioner when ``precondition`` is not given.
    weights : array, optional
        Positive weights: gap_i / w_i is a gap in the unit of ``scale`` (mortar rows).
    callback : callable, optional
        Called as callback(iteration, error) after each iteration (progress output).
    backend : optional
        Array backend of ``b``, ``q0`` and of what ``apply`` returns (:mod:`pillar_xval.contact._xp`;
        default numpy).  The iteration uses only the array API standard and the backend's
        ``dot``, so the same code runs on numpy or cupy arrays.
    force : float, optional
        Force control (Polonsky and Keer's own form, :class:`_ForceControl`): the given
        l.q, the approach an unknown returned as ``approach``.
    load : array, optional
        l, the gap's change per unit approach and each unknown's share of the force (default
        ones: cells of equal area).
    cut_outward : bool
        Cut from each direction its components that would take a zero pressure below zero
        (module docstring, "Directions at the bound"); not under force control, whose
        directions keep the force.

    Returns
    -------
    ContactSolution
        ``reentries`` counts the iterations in which cells entered the contact set.
    """
    be = NUMPY if backend is None else backend
    xp = be.xp
    dot = be.dot
    chunks = getattr(be, "chunks", one_piece)
    # The passes over the cells: one fused kernel each where the backend has them (a GPU).
    fused = getattr(be, "cg_passes", None)
    passes = fused if fused is not None and weights is None else ArrayPasses(xp, chunks, weights)
    if precondition is None:
        scaling = 1.0 if inverse_diagonal is None else inverse_diagonal
        precondition = lambda r, free: xp.where(free, r * scaling, 0.0)  # noqa: E731
    q = xp.maximum(be.asarray(q0, dtype=xp.float64), 0.0)
    fc = None
    if force is not None:
        fc = _ForceControl(xp, dot, float(force), load, b, precondition, scale)
        q = fc.start(q)
    # An operator may update the gap after a step that clips few pressures without a whole
    # application: apply.apply_few(index, values) -> A d, or None when it would not pay.
    apply_few = apply.apply_few if isinstance(apply, FewCellUpdates) else None
    # Mixed precision (module docstring): ``drift`` bounds the error the approximate
    # applications leave in the recursively updated gap.
    mixed = apply if isinstance(apply, MixedPrecision) else None
    approximate = None if mixed is None else mixed.approximate
    rel_error = float(mixed.approximate_error) if mixed is not None and approximate else 0.0
    step_apply = approximate or apply

    def exact_gap(q):
        gap = apply(q) + b
        return gap if fc is None else fc.offset(gap)

    def energy_of(q, gap):
        return _energy(dot, q, gap, b) + (0.0 if fc is None else fc.energy_term())

    # The first gap too: its error enters the bound like a step's.
    gap = step_apply(q)
    drift = rel_error * _max_abs(xp, gap)
    gap += b
    # Monotone once the residual stalls (module docstring): 1/2 q.A q + b.q, carried along.
    monotone, energy, best, since_best = False, 0.0, float("inf"), 0
    n = q.shape[0]
    t = z_old = xp.zeros_like(q)
    g_old = 1.0
    conj = False
    history = []
    since_refresh = 0
    entries = 0
    halved = 0  # truncated steps shortened, over the solve
    err = float("inf")
    # Vectors outside the free set are kept exactly zero, so plain dot products over all
    # cells equal the sums over the free set (boolean gathers are slow on 1e6 cells).
    # Updates are in place where the vector is the iteration's own (t, w, gap, and the
    # kept arrays of q's and the sets' next values): the same floating-point operations,
    # without fresh arrays (page faults on large grids).  The elementwise passes run in the
    # backend's ``chunks`` (threads on the FFT model's numpy path): each element gets the
    # same operations, and the reductions in them are exact (max, min, any), so the bits do
    # not depend on the split; the dot products run whole.
    active = q > 0.0
    free = xp.zeros_like(active)
    spare_q, spare_active = xp.empty_like(q), xp.zeros_like(active)
    for it in range(1, max_iterations + 1):
        if fc is not None:
            gap = fc.recentre(gap, active)
            scale = fc.scale
        err = passes.residual(gap, active, n, free) / scale
        if drift > 0.0 and (err <= tol or drift > DRIFT_SHARE * err * scale):
            gap = exact_gap(q)
            drift, since_refresh = 0.0, 0
            err = passes.residual(gap, active, n, free) / scale
        history.append(err)
        best, since_best = (err, 0) if err < best else (best, since_best + 1)
        if not monotone and since_best >= STALL_ITERATIONS:
            monotone, energy = True, energy_of(q, gap)
        if err <= tol:
            return ContactSolution(q, gap, True, it - 1, err, METHOD, "converged", history,
                                   entries, halved, None if fc is None else fc.zeta)
        z = precondition(gap, free)  # free: the contact set and gap < 0 (_residual)
        if fc is not None:
            z = fc.project(z, free)
        g_new = dot(gap, z)
        slope = None
        if conj and g_old > 0:
            beta = max((g_new - dot(z_old, gap)) / g_old, 0.0)
            passes.conjugate(t, beta, z, free, n)  # t may be z_old's: not read again
            if fc is not None:
                t = fc.reproject(t)
            slope = dot(gap, t)
            if slope <= 0.0:
                slope = None  # the projected conjugate direction no longer descends: restart
        if slope is None:
            t, slope = z, g_new
        z_old, g_old = z, g_new
        if cut_outward and fc is None:
            t, slope = _cut_outward(xp, dot, t, slope, q, gap)
        w = step_apply(t)
        denom = dot(w, t)
        if not denom > 0:
            return ContactSolution(q, gap, False, it, err, METHOD,
                                   f"non-positive curvature {denom:g}: operator not SPD",
                                   history, entries, halved, None if fc is None else fc.zeta)
        tau = slope / denom
        q_new, spare_q = spare_q, q  # q's array is free once q_new replaces it
        any_clipped = n > 0 and passes.step(q_new, q, tau, t, n) < 0.0
        clip_gap = None
        if any_clipped:
            if apply_few is not None:  # A of the clipping, q_new's change on few cells
                clipped = passes.negatives(q_new, n)
                values = -xp.take(q_new, clipped)
                clip_gap = apply_few(clipped, values, single=True) if approximate \
                    else apply_few(clipped, values)
            passes.clip(q_new, n)
        conj = True
        since_refresh += 1
        if (any_clipped and clip_gap is None) or since_refresh >= REFRESH_EVERY:
            gap = exact_gap(q_new)
            since_refresh = 0
            drift = 0.0
        else:  # the step was taken whole along t (exact up to A's rounding)
            largest = passes.update_gap(gap, w, tau, clip_gap, n)
            if approximate:
                drift += rel_error * largest
        if fc is not None and any_clipped:
            q_new, gap, ratio = fc.rescale(q_new, gap)
            drift *= ratio
        if monotone and any_clipped:
            # A truncated step: taken only if it lowers the energy, else shortened (module
            # docstring).  The gap's error bound enters as slack on the comparison.
            new_energy = energy_of(q_new, gap)
            halvings = 0
            while halvings < BACKTRACK_MAX and new_energy > energy + _energy_slack(
                    xp, drift, q_new, energy):
                halvings += 1
                tau *= 0.5
                q_new = xp.maximum(q - tau * t, 0.0)
                if fc is not None:
                    q_new = fc.start(q_new)
                gap = exact_gap(q_new)
                drift, since_refresh = 0.0, 0
                new_energy = energy_of(q_new, gap)
            halved += halvings
            conj = halvings == 0
            energy = new_energy
        elif monotone:
            energy -= 0.5 * tau * slope  # exact line search along t
        new_active, spare_active = spare_active, active
        entries += passes.new_set(new_active, q_new, active, n)
        q, active = q_new, new_active
        if callback is not None:
            callback(it, err)
    gap = exact_gap(q)
    if fc is not None:
        gap = fc.recentre(gap, q > 0.0)
        scale = fc.scale
    err = _residual(xp, gap, q > 0.0, weights, n) / scale
    history.append(err)
    converged = err <= tol
    return ContactSolution(q, gap, converged, max_iterations, err, METHOD,
                           "converged" if converged else
                           f"no convergence in {max_iterations} iterations (residual {err:.3g} "
                           f"> {tol:g})", history, entries, halved,
                           None if fc is None else fc.zeta)


class _ForceControl:
    """Polonsky and Keer's force control [1]: the approach zeta is the multiplier of the
    constraint l.q = F.

    - The gap carries the current approach, gap = A q + b - zeta l; at each iteration zeta
      moves to the mean gap over the contact set (sum of gaps over sum of l there), which
      makes the gap's mean on the set zero (:meth:`recentre`).
    - The directions are projected onto l.t = 0 in the preconditioner's metric,
      z - (l.z / l.M l) M l with M l the preconditioned load on the free set
      (:meth:`project`, :meth:`reproject`): a step along them keeps l.q = F, and its exact
      line search is that of the constrained minimum (the gradient's component along l is
      the multiplier's).
    - A step that truncates pressures at zero raises l.q: the pressures are rescaled to F and
      the gap with them, gap' = r gap + (1 - r)(b - zeta l), r = F / l.q (:meth:`rescale`).
    - The energy on the constraint, 1/2 q.A q + b.q, is 1/2 q.(gap + b) + zeta F / 2
      (:meth:`energy_term`), invariant under the approach's moves.

    ``load`` None means l = 1 (sums instead of products).  One preconditioner application
    more per iteration (M l) than under indentation control.
    """

    def __init__(self, xp, dot, force, load, b, precondition, scale):
        self.xp, self.dot, self.force, self.b = xp, dot, force, b
        self.load = xp.ones_like(b) if load is None else load
        self.unit = load is None
        self.precondition = precondition
        self.zeta = 0.0
        self.given_scale = scale
        self.m_load = None

    def ldot(self, v) -> float:
        return float(self.xp.sum(v)) if self.unit else self.dot(self.load, v)

    def start(self, q):
        """``q`` rescaled to the force; where it carries none, the first point to touch
        (least b / l)."""
        total = self.ldot(q)
        if not total > 0.0:
            touch = self.b if self.unit else self.b / self.load
            q = self.xp.astype(touch <= self.xp.min(touch), self.xp.float64)
            total = self.ldot(q)
        return q * (self.force / total)

    def offset(self, gap):
        """gap - zeta l, in place."""
        gap -= self.zeta if self.unit else self.zeta * self.load
        return gap

    def recentre(self, gap, active):
        on = self.xp.astype(active, self.xp.float64)
        area = self.ldot(on)
        if area > 0.0:
            shift = self.dot(gap, on) / area
            self.zeta += shift
            gap -= shift if self.unit else shift * self.load
        return gap

    @property
    def scale(self) -> float:
        return self.zeta if self.zeta > 0.0 else self.given_scale

    def project(self, z, free):
        self.m_load = self.precondition(self.load, free)
        self.norm = self.dot(self.load, self.m_load)
        return self.reproject(z)

    def reproject(self, t):
        if self.norm > 0.0:
            t -= (self.dot(self.load, t) / self.norm) * self.m_load
        return t

    def rescale(self, q, gap):
        ratio = self.force / self.ldot(q)
        q *= ratio
        gap *= ratio
        gap += (1.0 - ratio) * (self.b - (self.zeta if self.unit else self.zeta * self.load))
        return q, gap, ratio

    def energy_term(self) -> float:
        return 0.5 * self.zeta * self.force


def _cut_outward(xp, dot, t, slope, q, gap):
    """(t, slope) with t's components zeroed where q is zero and t positive (the step
    -tau t would take those pressures below zero, to be clipped at once); as given where
    there are none.  Such a cell of the free set has gap < 0, so the cut only raises the
    slope gap.t: the direction still descends."""
    outward = (q <= 0.0) & (t > 0.0)
    if not bool(xp.any(outward)):
        return t, slope
    cut = xp.where(outward, 0.0, t)
    return cut, dot(gap, cut)


def _energy(dot, q, gap, b) -> float:
    """1/2 q.A q + b.q = 1/2 q.(gap + b), the energy the iteration minimises, from the gap
    A q + b (two dot products, no temporary)."""
    return 0.5 * (dot(q, gap) + dot(q, b))


def _energy_slack(xp, drift, q, reference) -> float:
    """Round-off allowed when comparing energies: the gap's error bound ``drift`` (m) times
    the total pressure (the energy's error from the gap), plus 1e-12 of the reference."""
    slack = 1e-12 * abs(reference)
    return slack + 0.5 * drift * float(xp.sum(q)) if drift > 0.0 else slack


def _max_abs(xp, v) -> float:
    """max |v_i| in two reductions (no temporary)."""
    return max(float(xp.max(v)), -float(xp.min(v)), 0.0) if v.shape[0] else 0.0


class ArrayPasses:
    """The CG's passes over the cells as array operations, in the backend's ``chunks``
    (threads on the FFT model's numpy path); :class:`pillar_xval.contact._cuda.CudaPasses`
    fuses each into one kernel on a GPU, with the same values."""

    def __init__(self, xp, chunks, weights=None):
        self.xp, self.chunks, self.weights = xp, chunks, weights

    def residual(self, gap, active, n, free) -> float:
        return _residual(self.xp, gap, active, self.weights, n, self.chunks, free)

    def conjugate(self, t, beta, z, free, n) -> None:
        self.chunks(_conjugate(self.xp, t, beta, z, free), n)

    def step(self, q_new, q, tau, t, n) -> float:
        return _step(self.xp, self.chunks, q_new, q, tau, t, n)

    def clip(self, q, n) -> None:
        self.chunks(_clip(self.xp, q), n)

    def negatives(self, q, n):
        """The cells where q < 0, in increasing order (each chunk finds its own)."""
        xp, found = self.xp, {}

        def part(lo, hi):
            found[lo] = xp.nonzero(q[lo:hi] < 0.0)[0] + lo

        self.chunks(part, n)
        parts = [found[lo] for lo in sorted(found)]
        return parts[0] if len(parts) == 1 else xp.concat(parts)

    def update_gap(self, gap, w, tau, clip_gap, n) -> float:
        return _update_gap(self.xp, self.chunks, gap, w, tau, clip_gap, n)

    def new_set(self, new_active, q, active, n) -> bool:
        return _new_set(self.xp, self.chunks, new_active, q, active, n)


def _residual(xp, gap, active, weights, n, chunks=one_piece, free=None) -> float:
    """Max-norm min-map residual (m): |gap| on the contact set, interpenetration elsewhere
    (:func:`pillar_xval.contact.min_map_residual`, in one pass: this runs every iteration),
    in ``chunks``; ``free`` (a kept boolean array, optional) set to the free set, the
    contact set and the cells with gap < 0, in the same pass."""
    if n == 0:
        return 0.0
    # On the contact set |gap| >= -gap, so this is max(|gap| on the set, -gap anywhere):
    # the largest of -min(gap), gap on the set and 0 (gap times the set's indicator is gap
    # there and zero elsewhere, which the floor at 0 covers): the same value, in two
    # reductions and one product.
    extremes = []

    def part(lo, hi):
        if hi > lo:
            g = gap[lo:hi] if weights is None else gap[lo:hi] / weights[lo:hi]
            on = active[lo:hi]
            extremes.append((float(xp.max(g * xp.astype(on, xp.float64))),
                             float(xp.min(g))))
            if free is not None:
                free[lo:hi] = on | (gap[lo:hi] < 0.0)

    chunks(part, n)
    return max(-min(low for _, low in extremes), *(high for high, _ in extremes), 0.0)


def _conjugate(xp, t, beta, z, free):
    """``work(lo, hi)``: t = (beta t + z) restricted to the free set, in place (the product
    by the set's indicator, faster than where(free, ., 0))."""
    def part(lo, hi):
        tt = t[lo:hi]
        tt *= beta
        tt += z[lo:hi]
        tt *= xp.astype(free[lo:hi], xp.float64)
    return part


def _step(xp, chunks, q_new, q, tau, t, n) -> float:
    """q_new = q - tau t into the kept array ``q_new`` (as -(tau t) + q: the same bits), in
    ``chunks``; returns min(q_new)."""
    lows = []

    def part(lo, hi):
        if hi > lo:
            out = q_new[lo:hi]
            out[...] = t[lo:hi]
            out *= -tau
            out += q[lo:hi]
            lows.append(float(xp.min(out)))

    chunks(part, n)
    return min(lows)


def _clip(xp, q):
    """``work(lo, hi)``: q = max(q, 0), in place."""
    def part(lo, hi):
        q[lo:hi] = xp.maximum(q[lo:hi], 0.0)
    return part


def _update_gap(xp, chunks, gap, w, tau, clip_gap, n) -> float:
    """gap -= tau w (w scaled in place), then gap += ``clip_gap`` (or None), in ``chunks``;
    returns max|tau w| + max|clip_gap|, the scale of the update's rounding."""
    largest = []

    def part(lo, hi):
        if hi > lo:
            ww, g = w[lo:hi], gap[lo:hi]
            ww *= tau
            g -= ww
            if clip_gap is None:
                largest.append((_max_abs(xp, ww), 0.0))
            else:
                c = clip_gap[lo:hi]
                g += c
                largest.append((_max_abs(xp, ww), _max_abs(xp, c)))

    chunks(part, n)
    return max((a for a, _ in largest), default=0.0) + max((b for _, b in largest), default=0.0)


def _new_set(xp, chunks, new_active, q, active, n) -> bool:
    """new_active = q > 0 into the kept array ``new_active``, in ``chunks``; whether a cell
    entered (is in it and not in ``active``)."""
    entered = []

    def part(lo, hi):
        on = new_active[lo:hi]
        on[...] = q[lo:hi] > 0.0
        entered.append(bool(xp.any(on & ~active[lo:hi])))

    chunks(part, n)
    return any(entered)
