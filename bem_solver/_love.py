"""Love's influence coefficient: the integral of 1/|x - x'| over a uniformly loaded square.

The normal surface displacement of a half-space of compliance gamma = (1 - nu^2)/E under a
uniform pressure p on the rectangle |x'| <= a, |y'| <= b is u_z = gamma p / pi * D(x, y) with
(Love 1929; Johnson 1985, eq. 3.25)

    D = sum over the four corners (+-) of  G(x - x_c, y - y_c),
    G(u, v) = u asinh(v / |u|) + v asinh(u / |v|),   G -> 0 on the axes (c ln c -> 0).

Far from the square, D = A / r + A s^2 / (24 r^3) + O(s^4 / r^5) (A = s^2, the second moment of
a square is isotropic); the fourth-order remainder is below ``FAR_FIELD_RTOL`` beyond
``FAR_FIELD_RATIO`` sides, where the cheap two-term form replaces the exact one.

References
----------
.. [1] A. E. H. Love, "The stress produced in a semi-infinite solid by pressure on part of
   the boundary", Phil. Trans. R. Soc. A 228 (1929) 377-420.
.. [2] K. L. Johnson, *Contact Mechanics*, Cambridge University Press, 1985, sec. 3.9.
"""

from __future__ import annotations

import numpy as np

# Distance, in element sides, beyond which the two-term expansion is used; the relative error
# there is below FAR_FIELD_RTOL (the remainder falls as ~0.015 (s/r)^4; checked in
# tests/test_bem_operator.py), far below any discretisation error of the method.
FAR_FIELD_RATIO = 12.0
FAR_FIELD_RTOL = 1e-6


def _corner(u, v, xp=np):
    # u asinh(v/|u|) + v asinh(u/|v|): odd in u and in v, so that d2G/dudv = 1/sqrt(u^2+v^2)
    # in every quadrant; the removable zeros on the axes are set to 0 (divisors made 1 there,
    # so no division by zero is evaluated on any array library).
    u0, v0 = u == 0.0, v == 0.0
    t1 = xp.where(u0, 0.0, u * xp.asinh(v / xp.where(u0, 1.0, xp.abs(u))))
    t2 = xp.where(v0, 0.0, v * xp.asinh(u / xp.where(v0, 1.0, xp.abs(v))))
    return t1 + t2


def love_rectangle(x, y, a, b, xp=np):
    """Exact D(x, y) for the rectangle |x'| <= a, |y'| <= b (m); arrays broadcast.

    Multiply by gamma p / pi to get the displacement (m) under pressure p (Pa).  ``xp``: the
    array namespace of the arguments (numpy, cupy, any array API library).
    """
    x = xp.abs(xp.asarray(x, dtype=xp.float64))
    y = xp.abs(xp.asarray(y, dtype=xp.float64))
    return (_corner(x + a, y + b, xp) - _corner(x + a, y - b, xp)
            - _corner(x - a, y + b, xp) + _corner(x - a, y - b, xp))


def _line_term(w, divisor, hi, lo):
    """w (asinh(hi / divisor) - asinh(lo / divisor)): the two corners of one corner line."""
    t = np.arcsinh(hi / divisor)
    t -= np.arcsinh(lo / divisor)
    t *= w
    return t


def love_square_near(x, y, h):
    """D(x, y) / (2h)^2 for squares of half-side ``h`` (m) centred at the origin, at offsets
    (x, y) in the square's own frame: 1-D float64 numpy arrays of one length (the near pairs
    of an operator).  The corner sum of :func:`love_rectangle` regrouped by corner line, with
    a fixed number of array passes (no masks of zero corners: a zero distance to a corner
    line is made a unit divisor, its term being exactly zero); equal to it within rounding.
    """
    x = np.abs(x)
    y = np.abs(y)
    up, um = x + h, x - h  # up, vp > 0; um, vm of either sign or zero
    vp, vm = y + h, y - h
    au = np.abs(um)
    au[au == 0.0] = 1.0
    av = np.abs(vm)
    av[av == 0.0] = 1.0
    d = _line_term(up, up, vp, vm)
    d += _line_term(vp, vp, up, um)
    d -= _line_term(um, au, vp, vm)
    d -= _line_term(vm, av, up, um)
    d /= 4.0 * h * h
    return d


def love_far(r2, s2, xp=np):
    """Two-term far form of D at squared distance ``r2`` from a square of squared side ``s2``
    (m^2): A / r + A s^2 / (24 r^3), A = s^2.  Zero distances give 0 (divisor made 1), to be
    replaced by the exact form."""
    safe = xp.where(r2 > 0.0, r2, 1.0)
    return xp.where(r2 > 0.0, s2 / xp.sqrt(safe) * (1.0 + s2 / (24.0 * safe)), 0.0)


def love_square(x, y, side):
    """D(x, y) for a square of side ``side`` (m) centred at the origin, axis-aligned:
    exact within FAR_FIELD_RATIO sides, two-term expansion beyond; arrays broadcast."""
    x, y, side = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float),
                                     np.asarray(side, float))
    r2 = x * x + y * y
    s2 = side * side
    # Far form everywhere (cheap), then the few near entries exactly.
    out = love_far(r2, s2)
    near = np.nonzero(r2 <= FAR_FIELD_RATIO**2 * s2)
    if near[0].size:
        h = 0.5 * side[near]
        out[near] = love_rectangle(x[near], y[near], h, h)
    return out


def love_square_everywhere(x, y, side, xp=np):
    """:func:`love_square` for small arrays on any array library: both forms are evaluated
    everywhere and the exact one kept within FAR_FIELD_RATIO sides (no scatter)."""
    r2 = x * x + y * y
    s2 = side * side
    h = 0.5 * side
    return xp.where(r2 <= FAR_FIELD_RATIO**2 * s2, love_rectangle(x, y, h, h, xp),
                    love_far(r2, s2, xp))


def unit_force_influence(px, py, cx, cy, angle, side):
    """D / side^2 at points (px, py) (column vectors, shape (n, 1)) from squares centred at
    (cx, cy), rotated by ``angle`` (rad), of side ``side`` (m) (row vectors, shape (1, m)):
    the influence per unit force (1/m), shape (n, m).  The far form 1/r + s^2 / (24 r^3) is
    isotropic, so only the few near entries pay for the rotation and the exact formula."""
    px, py = np.atleast_2d(px), np.atleast_2d(py)
    cx, cy = np.atleast_2d(cx), np.atleast_2d(cy)
    angle, side = np.atleast_2d(angle), np.atleast_2d(side)
    dx = px - cx
    dy = py - cy
    r2 = dx * dx
    r2 += dy * dy
    s2 = side * side
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.sqrt(r2)
        out = inv * inv
        out *= s2 / 24.0
        out += 1.0
        out *= inv
    rows, cols = np.nonzero(r2 <= FAR_FIELD_RATIO**2 * s2)
    if rows.size:
        shape = np.broadcast_shapes(angle.shape, side.shape, dx.shape)
        a = np.broadcast_to(angle, shape)[rows, cols]
        h = 0.5 * np.broadcast_to(side, shape)[rows, cols]
        c, s = np.cos(a), np.sin(a)
        x, y = dx[rows, cols], dy[rows, cols]
        out[rows, cols] = love_rectangle(x * c + y * s, -x * s + y * c, h, h) / (4.0 * h * h)
    return out
