"""The Python API in one page: a scene, two models, a closed form, a convergence study.

Run it with ``python -m validation.examples.api_example [OUT_DIR]`` (a few seconds); the test
suite runs it too (tests/test_api_example.py), so it cannot rot.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from pillar_xval.scenes import analytic, load_scene
from validation.engine import Engine
from validation.output.report import write_solve_report
from validation.registry import run_model
from validation.studies.converge import converge_study, study_table


def main(out: Path) -> dict:
    """Solve the single-pillar preset (stiffer pillars, via an override) with the dense BEM
    and the axisymmetric FEM, compare both with the spring model, write the BEM's report
    folder and study the BEM's convergence; returns the numbers it prints (SI units)."""
    # A preset or a TOML file, with overrides in file units (as --set on the command line).
    scene = load_scene("single-pillar", ["pillars.E_Pa=1.6e7"])
    spring = analytic.spring_model(scene)  # the paper's closed form for one Hooke pillar

    bem = run_model("bem", scene, elements_per_diameter=11)  # every model: a ContactResult
    fem = run_model("fem-axisym", scene, mesh_size=2.0)
    for result in (bem, fem):
        assert result.converged, result.diagnostics["message"]  # a miss is reported, not raised
        print(f"{result.model:<11} F_T = {result.total_force_N * 1e6:.5f} uN, "
              f"sigma0 = {result.centre_pressure_Pa * 1e-3:.4g} kPa, "
              f"{result.wall_time_s:.2f} s")
    print(f"{'spring':<11} F_T = {spring.force * 1e6:.5f} uN, "
          f"sigma0 = {spring.centre_pressure * 1e-3:.4g} kPa")
    write_solve_report(bem, out / "bem")  # result.json, CSVs and pressure.png

    # Three refinements of the BEM on the engine (cached in out/converge-cases: a rerun
    # reads them back), observed order and GCI per quantity.
    with Engine("serial", quiet=True) as engine:
        study = converge_study("bem", scene, 3, out / "converge-cases", coarsest=7,
                               engine=engine)
    print(study_table(study))
    gci = study["studies"]["F_T"]["gci"]
    return {"bem_force_N": bem.total_force_N, "fem_force_N": fem.total_force_N,
            "spring_force_N": spring.force, "bem_order": gci["order"],
            "bem_richardson_N": gci["f_exact"]}


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
