"""pillar-xval's own package: the foundations every model stands on.

- :mod:`pillar_xval.outcome`: the result schema (``ContactResult``), atomic files, memory
  limits;
- :mod:`pillar_xval.scenes`: the problem (``Scene``, validated and in SI), scene files and
  presets, the lattice and the analytic library;
- :mod:`pillar_xval.contact`: the complementarity solvers (exact active set, constrained CG);
- :mod:`pillar_xval.closed_forms`: Hertz and the spring model as models;
- :mod:`pillar_xval.threads`: the threads a solve may use (the CPUs of the process, or the
  ``PILLAR_XVAL_THREADS`` override) and the libraries held to that count.

The solvers (``bem_solver``, ``fem_reference``), the meshes (``meshes``) and what users run
(``validation``: the CLI, studies, planner and pytest plugin) sit beside it.  Importing this
package imports none of its subpackages, so the command line starts fast.
"""

__all__: list[str] = []
