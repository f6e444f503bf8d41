"""The planner measured: ``calibrate`` writes its error and cost models (:mod:`.run`), from
its seeded scenes (:mod:`.scenes`), the lattice study's report (:mod:`.lattice_tables`), the
cases' costs (:mod:`.costs`) and the installed data's hand entries (:mod:`.hand`);
:mod:`.measured` holds what its tables share.  ``validate-plan``, which checks the planner's
choices on scenes it never saw, is a study of its own (:mod:`validation.studies.validate_plan`)."""

from .lattice_tables import (lattice_elastic_rung_tables, lattice_elastic_table,
                             lattice_hooke_table, load_lattice, relattice, with_lattice)
from .run import CALIBRATION_SEED, CANDIDATES, calibrate, write_data, write_document

__all__ = ["CALIBRATION_SEED", "CANDIDATES", "calibrate", "lattice_elastic_rung_tables",
           "lattice_elastic_table", "lattice_hooke_table", "load_lattice", "relattice",
           "with_lattice", "write_data", "write_document"]
