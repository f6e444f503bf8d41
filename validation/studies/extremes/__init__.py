"""Every model over the corners of the parameter space (:func:`run_extremes`, :mod:`.run`)
and its verdict table, summary and heat map (:mod:`.report`)."""

from .run import corner_scenes, model_options, run_extremes

__all__ = ["corner_scenes", "model_options", "run_extremes"]
