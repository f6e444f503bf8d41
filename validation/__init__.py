"""What users run.

- :mod:`validation.cli`: the ``pillar-xval`` commands, thin layers over the studies;
- :mod:`validation.engine`: the study engine (cases, cache, locks, executors, progress);
- :mod:`validation.studies`: converge, compare, gecit, tradeoff and sweep;
- :mod:`validation.ladders`: each model's refinement ladder and the compared quantities;
- :mod:`validation.verification` (GCI), :mod:`validation.profiles` (pressure-profile shape),
  :mod:`validation.plots`, :mod:`validation.report` (solve reports, figure utilities),
  :mod:`validation.render` (the off-screen 3D render);
- :mod:`validation.options`: the options a model takes and their allowed values;
- ``validation/examples/``: a sweep spec and the Python API example;
- :mod:`validation.models`: the registry of models by ``--model`` name;
- ``validation/bench/``: benchmarks run by the Makefile, never imported by the CLI.
"""
