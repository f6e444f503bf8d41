"""A model's declaration (:class:`Model`) and the one path that runs it (:meth:`Model.run`)."""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass, field
from collections.abc import Callable

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import Scene
from pillar_xval.scenes.floor import check_floor_scope
from pillar_xval.threads import limited

from .ladders import Ladder
from .options import OptionSpec

__all__ = ["CostLaw", "Model"]

# Arguments a solver may take that are no options: where to write its volume fields, and a
# sink for progress lines inside a long solve.  They change no result, so no case key holds
# them; a solver whose signature lacks one is called without it.
RUN_ARGUMENTS = ("vtu_path", "progress")


@dataclass(frozen=True)
class CostLaw:
    """How a model's wall time grows (the planner's cost fit, measured by ``calibrate``):
    time = sum_k c_k n^powers[k], n = exp(terms[term]) of the size function ``size`` of
    :mod:`validation.planner.costs` at the ladder's option; ``memory`` says where the memory
    estimate comes from (``{"kind": "estimate"}``: the size function's own), None: fitted;
    ``workload``: the reference workloads of :mod:`validation.planner.machine` its time
    follows from one machine or thread count to another, as (name, share) pairs."""

    size: str
    term: str | None
    powers: tuple
    memory: dict | None = None
    workload: tuple = (("assembly", 1.0),)


@dataclass(frozen=True)
class Model:
    """Everything the toolkit knows of one model, by its ``--model`` name.

    ``solver`` is ``"module:function"``, imported on first use (a command that runs only the
    BEM never imports scikit-fem or gmsh); ``function(scene, **options)`` returns a
    :class:`pillar_xval.outcome.ContactResult`.  ``options`` are the keywords it takes, with
    their specs (:mod:`.options`).  The rest say how the studies use it:

    - ``ladder``: how it is refined (``converge``, ``compare``, ``gecit``, ``tradeoff``, the
      planner's candidates); None for a model without a resolution;
    - ``physics``: models of equal physics share a Richardson reference (``tradeoff``);
      "hooke-pillar", "elastic-pillar", or "" (its own); at the model's default options: an
      option whose spec maps its choices to a physics decides it per case (``pillars =
      elastic`` is "elastic-pillar": :meth:`physics_of`);
    - ``expected_order``: the order of its error in the ladder's cell size, where known; an
      observed order far from it marks an estimate as pre-asymptotic (``tradeoff``);
    - ``scopes``: the regimes (flat, single, multi) where the planner may choose it, and
      ``scope_note``, why not elsewhere; a model with scopes is a planner candidate at every
      rung of its ladder (or once, without a ladder: a closed form);
    - ``cost``: its cost law (``calibrate`` fits it; the planner predicts with the fit);
    - ``reference_rungs``: per regime, the rungs whose Richardson estimate is the best
      reference there (``validate-plan``);
    - ``robustness``: the cheap options ``extremes`` runs it at (None: not run there), and
      ``robustness_quick``, those of its fast subset; ``keeps_fields``: its result arrays are
      kept for the pressure check there; ``weak_contact``: its contact holds in a weak
      (mortar) sense, so the pointwise gap may dip by up to the FEMs' own limit;
    - ``expensive``: ``tradeoff`` runs it only when named (minutes per rung);
    - ``code``: packages beyond the engine's ``COMPUTING_PACKAGES`` whose source and data
      decide its results; the case key hashes them (:mod:`validation.engine._case`);
    - ``force_control``: how it solves a force-controlled scene: ``"native"``, its solver
      takes one itself (and says how in its module); ``"outer"`` (the default, for a model
      registered without a thought for it), :meth:`run` finds the indentation that carries
      the force by whole solves under indentations
      (:func:`pillar_xval.contact.solve_at_force`);
    - ``floor``: its candidates include the floor between the pillars, so it solves a scene
      whose lens reaches the floor; one without it refuses such a scene (its given
      indentation before the solve, the one it solved under a force after it:
      :func:`pillar_xval.scenes.floor.check_floor_scope`).
    - ``reference_for``: the roles in which the studies take it as the reference
      (:data:`REFERENCE_ROLES`: "single-pillar", the elastic pillar of one pillar or a flat
      scene; "lattice", a lattice's); :func:`validation.registry.reference_model`;
    - ``request``: ``"module:function"`` that checks its options together where a spec
      cannot (``auto``: the planner's request, ``function(**options)`` raising InputError),
      imported on first use; "" for none.
    """

    name: str
    solver: str
    summary: str
    options: dict[str, OptionSpec] = field(default_factory=dict)
    ladder: Ladder | None = None
    physics: str = ""
    expected_order: float | None = None
    scopes: tuple[str, ...] = ()
    scope_note: str = ""
    cost: CostLaw | None = None
    reference_rungs: dict[str, tuple] = field(default_factory=dict)
    robustness: dict | None = None
    robustness_quick: dict | None = None
    keeps_fields: bool = False
    weak_contact: bool = False
    expensive: bool = False
    code: tuple[str, ...] = ()
    force_control: str = "outer"
    floor: bool = False
    request: str = ""
    reference_for: tuple[str, ...] = ()

    @property
    def function(self) -> Callable[..., ContactResult]:
        """The solver function (imports its module)."""
        module, name = self.solver.split(":")
        return getattr(importlib.import_module(module), name)

    @property
    def candidate(self) -> bool:
        """Whether the planner may choose it."""
        return bool(self.scopes)

    def check_request(self, options: dict) -> None:
        """Check the options together with the model's ``request`` function, if any."""
        if self.request:
            module, name = self.request.split(":")
            getattr(importlib.import_module(module), name)(**options)

    def takes(self, argument: str) -> bool:
        """Whether the solver's signature has ``argument`` (False when it cannot be read)."""
        try:
            return argument in inspect.signature(self.function).parameters
        except (ImportError, AttributeError, ValueError, TypeError):
            return False

    def default(self, option: str):
        """The solver's own default of ``option`` (None where it has none)."""
        parameter = inspect.signature(self.function).parameters.get(option)
        if parameter is None or parameter.default is inspect.Parameter.empty:
            return None
        return parameter.default

    def physics_of(self, options: dict | None = None) -> str:
        """The physics of this model run with ``options``: the declared ``physics``, unless
        one of its options with a physics per choice (its spec's ``physics``: ``pillars``)
        is given a choice that says otherwise."""
        for name, value in (options or {}).items():
            spec = self.options.get(name)
            if spec is not None and value is not None:
                physics = dict(spec.physics).get(value)
                if physics:
                    return physics
        return self.physics

    def solver_options(self, options: dict) -> dict:
        """The options this model takes, without those left to its default (None)."""
        return {k: v for k, v in options.items() if k in self.options and v is not None}

    def run(self, scene: Scene, options: dict, *, vtu_path=None,
            progress=None) -> ContactResult:
        """Solve ``scene``: the options it takes (others are ignored: a study may hand every
        model the same set) and the run arguments its solver has, with BLAS, MKL and OpenMP
        held to :func:`pillar_xval.threads.thread_count` threads (the solvers' own threads
        read the same count)."""
        kwargs = self.solver_options(options)
        for name, value in zip(RUN_ARGUMENTS, (vtu_path, progress)):
            if value is not None and self.takes(name):
                kwargs[name] = value
        if not self.floor:
            check_floor_scope(scene, self.name)  # a given indentation only
        with limited():
            if scene.force_N is not None and self.force_control != "native":
                from pillar_xval.contact import solve_at_force
                from pillar_xval.scenes import analytic

                result = solve_at_force(lambda at: self.function(at, **kwargs), scene,
                                        guess=analytic.indentation_estimate(scene),
                                        how=f"{self.name}, by solves under indentations")
            else:
                result = self.function(scene, **kwargs)
        if not self.floor and scene.force_N is not None:
            check_floor_scope(scene, self.name, result.indentation_m, "solved by the model")
        return result

