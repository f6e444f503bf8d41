"""The model registry: one declaration per model (:mod:`.models`), and the one path that runs
a model (:func:`run_model`), used by the CLI, the engine and the planner.

- :class:`Model` (:mod:`.model`): name, solver, options with their allowed values, ladder,
  physics, expected order, planner scopes, cost law, the studies' settings;
- :class:`OptionSpec` and the option specs (:mod:`.options`), read from the solvers' own
  constants; :func:`check_option`, :func:`flag`;
- :class:`Ladder` and the compared :data:`QUANTITIES` (:mod:`.ladders`).

Everything else is derived from the declarations: :data:`MODEL_OPTIONS` (the CLI's option
vocabulary, :func:`option_vocabulary`), :func:`ladders`, :func:`candidates` (the planner's),
... : functions of :data:`MODELS`, so that a model registered later (a test's fake) joins them.
"""

from __future__ import annotations

import importlib

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import InputError, Scene

from .ladders import (FLOOR_QUANTITIES, LOAD_QUANTITIES, QUANTITIES, Ladder, Quantity,
                      quantity_values)
from .model import CostLaw, Model
from .models import DECLARED
from .options import OptionSpec, check_option, flag

__all__ = ["FLOOR_QUANTITIES", "LOAD_QUANTITIES", "MODELS", "QUANTITIES", "REFERENCE_ROLES",
           "CostLaw", "Ladder", "Model", "OptionSpec", "Quantity", "candidates", "check_option",
           "check_options", "default_pillars", "family_options", "flag", "get_model",
           "ladder_for", "ladders", "model_names", "option_vocabulary", "quantity_values",
           "reference_model", "run_model", "scene_defaults", "stored_operator"]

# Every model by its --model name, in declaration order (tests register fakes here).
MODELS: dict[str, Model] = {m.name: m for m in DECLARED}


def model_names() -> list[str]:
    return sorted(MODELS)


# The roles a study's reference model plays (a model declares them: Model.reference_for).
REFERENCE_ROLES = ("single-pillar", "lattice")


def reference_model(role: str) -> str:
    """The model the studies take as the reference in ``role`` (one of
    :data:`REFERENCE_ROLES`): the one model whose declaration names it."""
    found = [m.name for m in MODELS.values() if role in m.reference_for]
    if role not in REFERENCE_ROLES or len(found) != 1:
        raise ValueError(f"reference role {role!r}: {len(found)} models declare it "
                         f"(roles: {', '.join(REFERENCE_ROLES)})")
    return found[0]


def get_model(name: str) -> Model:
    """The declaration of ``name``; InputError (one line) for an unknown name."""
    if name not in MODELS:
        raise InputError(f"--model {name!r}: unknown; available: {', '.join(model_names())}")
    return MODELS[name]


def run_model(name: str, scene: Scene, *, vtu_path=None, progress=None,
              **options) -> ContactResult:
    """Run model ``name`` on ``scene``: the one path of the CLI, the engine and the planner.

    Options the model does not take, and those that are None (the model's default), are left
    out; ``vtu_path`` and ``progress`` go to a solver that has them (:meth:`Model.run`)."""
    return get_model(name).run(scene, options, vtu_path=vtu_path, progress=progress)


def default_pillars(scene: Scene) -> str | None:
    """The pillar model a command runs where the user names none: the elastic pillar on a
    scene whose pillars are elastic (the Hooke spring puts sigma0 3-60 % low in a lattice),
    the paper's Hooke spring on rigid pillars (within about 1 % there, and no compliance to
    build); None on a flat scene, which has no pillar model."""
    if scene.pillars is None:
        return None
    return "hooke" if scene.pillars.material.rigid else "elastic"


def scene_defaults(model: str, scene: Scene, options: dict) -> dict:
    """``options`` with the defaults that follow the scene: ``pillars`` (:func:`default_pillars`)
    for a model that takes it, where the options do not give it, on either device.  The
    commands, the spec
    files and the pytest fixture apply it (so a case's key and its table row name the pillar
    model); the solvers themselves keep the paper's Hooke spring as their default."""
    entry = MODELS.get(model)
    pillars = default_pillars(scene)
    if entry is None or "pillars" not in entry.options or pillars is None \
            or options.get("pillars") is not None:
        return dict(options)
    return {**options, "pillars": pillars}


def check_options(model: str, options: dict, where: str = "",
                  scene: Scene | None = None) -> dict:
    """``options`` when ``model`` takes each of them with an allowed value (its spec's range or
    choices, every number finite) and, where the model checks its options together (``auto``:
    the planner's request), they pass that too; otherwise InputError, one line that starts
    with ``where`` and names the model, the option and its value.  With ``scene``: an elastic
    pillar on a flat scene is refused too.  What a spec, a sweep or a test hands a model is
    checked here, before anything is solved."""
    import math

    prefix = f"{where} " if where else ""
    entry = MODELS.get(model)
    if entry is None:
        raise InputError(f"{prefix}{model!r}: unknown model; available: "
                         f"{', '.join(model_names())}")
    if not isinstance(options, dict):
        raise InputError(f"{prefix}{model}: its options must be a table, not {options!r}")
    unknown = sorted(set(options) - set(entry.options))
    if unknown:
        raise InputError(f"{prefix}{model}: unknown option(s) {', '.join(map(repr, unknown))}; "
                         f"it takes {', '.join(entry.options) or 'none'}")
    for name, value in options.items():
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"{prefix}{model}: {name} = {value!r}: expected a finite number")
        check_option(name, value, where=f"{prefix}{model}: {name} =", spec=entry.options[name])
    if scene is not None and scene.pillars is None and options.get("pillars") == "elastic":
        raise InputError(f"{prefix}{model}: pillars = 'elastic': the scene is flat, it has no "
                         "pillars to model")
    try:
        entry.check_request(options)
    except InputError as exc:
        raise InputError(f"{prefix}{model}: {exc}") from None
    return options


# The stores of cached operators a result may name in its diagnostics["operators"] (records
# {"store", "key", "sha256"}): each a "module:function" that gives the content hash of the valid
# operator the store holds under a key now (None: none, or a damaged one), imported on first
# use like the solvers.
OPERATOR_STORES = {"pillar-compliance": "fem_reference._compliance_store:stored_digest"}


def stored_operator(store, key) -> str | None:
    """The content hash of the operator that ``store`` holds under ``key`` now (None: no
    such store, or no valid operator under that key)."""
    if store not in OPERATOR_STORES:
        return None
    module, name = OPERATOR_STORES[store].split(":")
    return getattr(importlib.import_module(module), name)(key)


def option_vocabulary() -> dict[str, OptionSpec]:
    """Every option of every registered model, by name, with one spec per name (the hull of
    the models' ranges where they differ: :meth:`OptionSpec.hull`)."""
    out: dict[str, OptionSpec] = {}
    for model in MODELS.values():
        for name, spec in model.options.items():
            out[name] = out[name].hull(spec) if name in out else spec
    return out


def family_options() -> list[str]:
    """The refinement options, one per model family."""
    return [name for name, spec in option_vocabulary().items() if spec.family]


def ladders() -> dict[str, Ladder]:
    """The ladder of every model that has one, in declaration order."""
    return {m.name: m.ladder for m in MODELS.values() if m.ladder is not None}


def ladder_for(model: str) -> Ladder:
    """The refinement ladder of ``model``; InputError (one line) for a model without one."""
    known = ladders()
    if model not in known:
        raise InputError(f"--model {model!r}: no refinement ladder; known: "
                         f"{', '.join(sorted(known))}")
    return known[model]


def candidates() -> list[dict]:
    """The planner's candidates: each rung of each candidate model's ladder, then the closed
    forms, with the regimes where each may run and why not elsewhere."""
    out = []
    for model in MODELS.values():
        if not model.candidate or model.ladder is None:
            continue
        ladder = model.ladder
        short = model.options[ladder.option].short or ladder.option
        for value in ladder.rungs:
            out.append({"model": model.name, "options": ladder.options_at(value),
                        "label": f"{model.name} {short}={value:g}",
                        "regimes": list(model.scopes), "scope": model.scope_note,
                        "closed_form": False})
    for model in MODELS.values():
        if model.candidate and model.ladder is None:
            out.append({"model": model.name, "options": {}, "label": model.name,
                        "regimes": list(model.scopes), "scope": model.scope_note,
                        "closed_form": True})
    return out
