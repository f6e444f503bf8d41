"""The paper's Figs. 3-8 (:func:`run_figures`, :mod:`.run`): the scenes of Table 1
(:mod:`.scenes`), the single-pillar threshold (:mod:`.thresholds`), the master-curve fits
(:mod:`.fits`), the element maps of Fig. 3 (:mod:`.maps`), the figures (:mod:`.plots`), their
CSVs (:mod:`.files`), the paper's claims checked per pillar model (:mod:`.claims`) and
``figures.md`` (:mod:`.report`)."""

from .run import DENSE_MODELS, HERTZ_BAND, run_figures

__all__ = ["DENSE_MODELS", "HERTZ_BAND", "run_figures"]
