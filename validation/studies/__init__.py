"""The studies behind the commands, each a function of scenes and an engine that returns
JSON-ready data, plus the writers of its report files: ``converge`` (grid convergence of one
model), ``compare`` (BEM against FEM with uncertainty), ``gecit`` (the Hooke pillar against
the elastic one), ``tradeoff`` (time, memory and error per rung) and ``sweep`` (a grid of
scenes and models into one table)."""
