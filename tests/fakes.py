"""Fake models with known discretisation errors, registered in place of the real ``bem`` and
``fem-axisym`` by the ``fakes`` fixture (tests/conftest.py): the studies' arithmetic is
checked against these closed forms."""

import math

import numpy as np

from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import analytic

CALLS: list[tuple] = []


def register(monkeypatch, name: str, solver: str, options=None, **fields):
    """Put ``solver`` ("module:function") in place of model ``name``'s for this test: the
    declaration keeps its other fields; ``options`` narrows its options to these names, or (a
    dict of specs) declares them; a model not registered yet is declared with ``fields``."""
    from dataclasses import replace

    from validation.registry import MODELS, Model

    model = MODELS.get(name) or Model(name, solver, f"fake {name}")
    fields.setdefault("force_control", "outer")  # a fake solves under indentations only
    if options is None:
        options = model.options
    elif not isinstance(options, dict):
        options = {k: model.options[k] for k in options}
    monkeypatch.setitem(MODELS, name, replace(model, solver=solver, options=options, **fields))
# Fake discretisation errors: f = f_exact (1 + C_FEM h^2) (FEM, h = mesh_size) and
# f_exact (1 + C_BEM / P^2) (BEM): both second order by construction.
C_FEM, C_BEM = 0.02, 0.5


def edge_exponent_of(scene) -> float:
    """The fake FEM's edge exponent: 1/2 for a rigid pillar, falling to 0 for a soft one."""
    ratio = scene.pillars.material.E_Pa / scene.lens.material.E_Pa
    return 0.5 if math.isinf(ratio) else 0.5 * ratio / (1.0 + ratio)


def _profile(scene, n: int = 60):
    """Nodes graded towards the edge and sigma_0 (1 - (2r/d)^2)^(-lambda)."""
    if scene.is_flat:
        hz = analytic.hertz(scene)
        r = hz.contact_radius * np.linspace(0, 1, n)
        return r, hz.pressure(r)
    d = scene.pillars.diameter_m
    r = 0.5 * d * (1.0 - np.geomspace(1e-4, 1.0, n)[::-1])
    r[0] = 0.0
    r = np.append(r, 0.5 * d)
    s = analytic.spring_model(scene).centre_pressure
    inner = np.clip(1 - (2 * r / d) ** 2, 1e-4 * 2e-4, None)
    return r, s * inner ** (-edge_exponent_of(scene))


def _result(model, scene, factor, disc):
    if scene.is_flat:
        ref = analytic.hertz(scene)
        f, s0, a, area = ref.force, ref.centre_pressure, ref.contact_radius, ref.contact_area
    else:
        ref = analytic.spring_model(scene)
        d = scene.pillars.diameter_m
        f, s0, a, area = ref.force, ref.centre_pressure, d / 2, math.pi * d * d / 4
    r, p = _profile(scene)
    forces = [] if scene.is_flat else [PillarForce(0, 0, 0.0, 0.0, f * factor)]
    return ContactResult(
        model=model, scene=scene.to_dict(), discretisation=disc, total_force_N=f * factor,
        centre_pressure_Pa=s0 * factor, contact_radius_m=a, real_contact_area_m2=area,
        pillars_in_contact=0 if scene.is_flat else 1, pillar_forces=forces, converged=True,
        iterations=1, wall_time_s=0.01,
        pillar_top_profile={"r_m": r.tolist(), "pressure_Pa": (p * factor).tolist()})


def fake_fem(scene, mesh_size=1.0, *, vtu_path=None):
    CALLS.append(("fem", mesh_size))
    if vtu_path is not None:
        import meshio

        pts = np.array([[0, 0, 0], [1e-5, 0, 0], [1e-5, 1e-5, 0], [0, 1e-5, 0]], dtype=float)
        meshio.write(str(vtu_path), meshio.Mesh(
            pts, [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))],
            point_data={"von_mises_Pa": np.array([1.0, 2.0, 3.0, 4.0])}))
    return _result("fem-axisym", scene, 1.0 + C_FEM * mesh_size**2, {"mesh_size": mesh_size})


def fake_bem(scene, elements_per_diameter=11, cells="covered", contact="exact"):
    CALLS.append(("bem", elements_per_diameter))
    return _result("bem", scene, 1.0 + C_BEM / elements_per_diameter**2,
                   {"elements_per_diameter": elements_per_diameter, "cells": cells})
