"""Every model over the corners of the parameter space (:func:`run_extremes`, :mod:`.run`)
and its verdict table, summary and heat map (:mod:`.report`)."""

from .run import MODELS, corner_scenes, run_extremes

__all__ = ["MODELS", "corner_scenes", "run_extremes"]
