"""The planner measured and checked: ``calibrate`` writes its error and cost models
(:mod:`.run`), ``validate-plan`` checks its choices on scenes it never saw (:mod:`.validate`);
both draw their seeded scenes from :mod:`.scenes`."""

from .run import (CALIBRATION_SEED, CANDIDATES, calibrate, lattice_elastic_table,
                  lattice_hooke_table, load_lattice,
                  relattice, with_lattice, write_data, write_document)

__all__ = ["CALIBRATION_SEED", "CANDIDATES", "calibrate", "lattice_elastic_table",
           "lattice_hooke_table", "load_lattice",
           "relattice", "with_lattice", "write_data", "write_document"]
