"""The planner: which model a scene needs for a tolerance, and what it will cost
(:func:`plan`, :func:`solve_auto`: :mod:`.plan`).  A model-selection service used by
``plan``, ``solve --model auto`` and any study, not a study itself.

- :mod:`.features`: a scene's regime and the features the tables are interpolated in;
- :mod:`.tables`: the error tables and cost fits, read from ``data/*.json``;
- :mod:`.costs`: the sizes of a solve known before it runs (what the cost fits are written in).

Its data (``data/error_models.json``, ``data/cost_models.json``) is measured by
``pillar-xval calibrate`` (:mod:`validation.studies.calibrate`).
"""

from .plan import (DEFAULT_QUANTITIES, DEFAULT_TOLERANCE, check_request, plan, plan_text,
                   solve_auto)

__all__ = ["DEFAULT_QUANTITIES", "DEFAULT_TOLERANCE", "check_request", "plan", "plan_text",
           "solve_auto"]
