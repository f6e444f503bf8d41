"""What users run (ARCHITECTURE.md: the rooms and their one-way arrows).

- :mod:`validation.registry`: one declaration per model and the one path that runs it;
- :mod:`validation.planner`: which model a scene needs for a tolerance, at what cost;
- :mod:`validation.engine`: the study engine (cases, keys, cache, locks, executors, progress);
- :mod:`validation.studies`: the studies behind the commands;
- :mod:`validation.analysis`: grid convergence and GCI, pressure-profile shape;
- :mod:`validation.output`: plots, solve reports, the renders of FEM fields;
- :mod:`validation.cli`: the ``pillar-xval`` commands, thin layers over the studies;
- ``validation/examples/``: a sweep spec and the Python API example;
- ``validation/bench/``: benchmarks run by the Makefile, never imported by the CLI.
"""
