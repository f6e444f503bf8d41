"""Sweeps: a grid of scenes x models into one tidy table (:mod:`.run`, the spec format; the
grid itself: :mod:`.grid`)."""

from .run import (Axis, ModelSpec, Sweep, SweepCase, crossed, estimate_cost, estimate_seconds,
                  linear, log, run_sweep, run_sweep_cases, scene_columns, table_rows,
                  write_table, zipped)

__all__ = ["Axis", "ModelSpec", "Sweep", "SweepCase", "crossed", "estimate_cost",
           "estimate_seconds", "linear", "log", "run_sweep", "run_sweep_cases", "scene_columns",
           "table_rows", "write_table", "zipped"]
