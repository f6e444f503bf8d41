"""Analysis of results: grid convergence, Richardson extrapolation and GCI
(:mod:`.verification`), the shape of a pillar-top pressure profile (:mod:`.profiles`)."""
