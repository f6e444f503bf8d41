"""Closed forms as models (``hertz``, ``spring``): they return a :class:`pillar_xval.outcome.ContactResult`
like every numerical model (:mod:`._models`).  The formulas themselves are the scene's
analytic library, :mod:`pillar_xval.scenes.analytic`."""

from ._models import solve_hertz, solve_spring

__all__ = ["solve_hertz", "solve_spring"]
