"""The studies behind the commands, each a function of scenes and an engine that returns
JSON-ready data, plus the writers of its report files:

- ``converge``: grid convergence of one model (observed order, Richardson, GCI);
- ``compare``: the BEM against a FEM on one scene, with both uncertainties;
- ``gecit``: the Hooke pillar against the elastic one over E_p/E_l and h/d;
- ``tradeoff``: time, memory and error per rung of each model's ladder;
- ``lattice``: the Hooke BEM against fem-3d on lattices;
- ``regimes``: the model the planner picks over Phi x zeta/h and the Hooke pillar's sigma0
  error (plans only, no engine);
- :mod:`.sweep`: a grid of scenes and models into one table;
- :mod:`.figures`: the paper's Figs. 3-8;
- :mod:`.extremes`: every model over the corners of the parameter space;
- :mod:`.calibrate`: the planner's error and cost models (``calibrate``) and their check on
  unseen scenes (``validate-plan``).

Model selection itself is no study: :mod:`validation.planner`.
"""
