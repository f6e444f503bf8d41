"""Exact area and centroid of a disk cut by axis-aligned rectangles (closed form, vectorised).

Shared by the cells of the dense model and the grid of the FFT model: a pillar-top cell
carries its exact covered area and is loaded and collocated at the centroid of that part.
"""

from __future__ import annotations

import numpy as np

from pillar_xval.scenes.analytic import float_array


def _segment_integral(y, a, b, rad):
    """Integral over x in [a, b] (already clipped to [-rad, rad]) of clip(y, -s(x), s(x)),
    s(x) = sqrt(rad^2 - x^2); arrays broadcast."""
    def prim(x):  # antiderivative of s(x)
        xc = np.clip(x / rad, -1.0, 1.0)
        return 0.5 * rad * rad * (xc * np.sqrt(1.0 - xc * xc) + np.arcsin(xc))

    w = np.sqrt(np.maximum(rad * rad - y * y, 0.0))
    a_in = np.clip(a, -w, w)
    b_in = np.clip(b, -w, w)
    # Where |x| <= w the chord covers y itself; elsewhere the clip is +-s(x).
    inner = y * (b_in - a_in)
    outer = np.sign(y) * ((prim(b) - prim(a)) - (prim(b_in) - prim(a_in)))
    return inner + outer


def disk_rectangle_area(x0, x1, y0, y1, rad):
    """Exact area of the disk of radius ``rad`` centred at the origin intersected with the
    rectangles [x0, x1] x [y0, y1] (same unit as the inputs, squared); arrays broadcast.

    Area = integral over x of [clip(y1, -s, s) - clip(y0, -s, s)], s = sqrt(rad^2 - x^2),
    integrated in closed form.
    """
    a = np.clip(x0, -rad, rad)
    b = np.clip(x1, -rad, rad)
    area = _segment_integral(float_array(y1), a, b, rad) \
        - _segment_integral(float_array(y0), a, b, rad)
    return np.maximum(area, 0.0)


def _segment_moment(y, a, b, rad):
    """Integral over x in [a, b] (clipped to [-rad, rad]) of x clip(y, -s(x), s(x))."""
    def prim(x):  # antiderivative of x s(x)
        return -np.maximum(rad * rad - x * x, 0.0) ** 1.5 / 3.0

    w = np.sqrt(np.maximum(rad * rad - y * y, 0.0))
    a_in = np.clip(a, -w, w)
    b_in = np.clip(b, -w, w)
    inner = 0.5 * y * (b_in * b_in - a_in * a_in)
    outer = np.sign(y) * ((prim(b) - prim(a)) - (prim(b_in) - prim(a_in)))
    return inner + outer


def disk_rectangle_centroid(x0, x1, y0, y1, rad):
    """Centroid (x, y) of the disk of radius ``rad`` (centred at 0) cut by the rectangles
    [x0, x1] x [y0, y1]; first moments integrated in closed form like
    :func:`disk_rectangle_area`.  Arrays broadcast; the area must be > 0."""
    area = disk_rectangle_area(x0, x1, y0, y1, rad)
    a, b = np.clip(x0, -rad, rad), np.clip(x1, -rad, rad)
    c, d = np.clip(y0, -rad, rad), np.clip(y1, -rad, rad)
    mx = _segment_moment(float_array(y1), a, b, rad) \
        - _segment_moment(float_array(y0), a, b, rad)
    my = _segment_moment(float_array(x1), c, d, rad) \
        - _segment_moment(float_array(x0), c, d, rad)
    return mx / area, my / area
