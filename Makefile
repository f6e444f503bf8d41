# Set-up is part of every target: a fresh clone needs only `make demo` or `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: demo study-gecit study-lattice study-floor figures test test-slow bench-bem bench-fft bench-gpu bench-fem3d \
	bench-elastic bench-fem3d-floor bench-fem3d-floor-levels bench-mesh3d-ab bench-engine bench-figures bench-startup bench-force \
	bench-floor bench-floor-ab bench-floor-gap bench-sweep bench-threads bench-planner-threads \
	clean calibrate validate-planner extremes regimes docs lint reproduce lent-kit \
	bench-assembly3d-ab

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# The main job: the BEM (elastic pillars, its default there: the pillar compliance of the
# presets' one pillar kind built once, ~20 s, then cached) against the FEM on the
# single-pillar and Hertz scenes (axisymmetric FEM), then a three-way comparison on a lattice
# of 43 pillars (Phi = 0.2): the Hooke BEM and the elastic-pillar BEM against one fem-3d run
# (mesh_size 2.83, 2, 1.41), about 3 minutes; the table with its verdicts in
# compare-lattice/summary.md, the centre pillar's profiles in its profiles.png; then the
# paper's Fig. 3 scenes with the BEM (elastic pillars).
demo: $(STAMP)
	$(VENV)/bin/pillar-xval compare --scene single-pillar --out $(OUT)/compare-single-pillar
	$(VENV)/bin/pillar-xval compare --scene hertz --out $(OUT)/compare-hertz
	$(VENV)/bin/pillar-xval compare --scene paper-fig3-sparse --set pillars.surface_fraction=0.2 \
		--pillars both --out $(OUT)/compare-lattice
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-sparse --out $(OUT)/fig3-sparse
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-dense --out $(OUT)/fig3-dense

# The Gecit-like study: Hooke-spring BEM against the elastic-pillar FEM over E_p/E_l and h/d
# (a few minutes; resumes after an interruption).
study-gecit: $(STAMP)
	$(VENV)/bin/pillar-xval gecit --out $(OUT)/gecit

# The multi-pillar cross-validation: the Hooke BEM and the elastic-pillar BEM against fem-3d over
# Phi in {0.03, 0.1, 0.2, 0.4} x E_p/E_l in {0.1, 1, 10, 1e6} with E_s = E_l, and Phi in {0.2, 0.4}
# x E_p/E_l in {0.1, 10} at the paper's E_s = E_p; the elastic BEM judged against its targets
# (about 1.5 hours on 2 cores: the E_s = E_p scenes' fem-3d adds 15-25 minutes, the elastic
# column about 5 plus 20-60 s per pillar kind on a fresh cache; resumes).  Then at zeta = 0.05 and
# 0.015 um the grid with E_p/E_l = 100 added, at E_s = E_l and at E_s = E_p (36 scenes each, about
# 15 and 10 minutes), and at zeta = 0.3 um the same for Phi = 0.03 and 0.1 (18 scenes, about 10
# minutes; the denser lattices' fem-3d at zeta = 0.3 um takes 5-10 minutes a scene): the
# planner's lattice tables get a zeta axis and a substrate axis.
study-lattice: $(STAMP)
	$(VENV)/bin/pillar-xval lattice --out $(OUT)/lattice
	$(VENV)/bin/pillar-xval lattice --zeta-um 0.05 --ratios 0.1,1,10,100,1e6 --paper-scenes grid \
		--out $(OUT)/lattice-zeta0.05
	$(VENV)/bin/pillar-xval lattice --zeta-um 0.015 --ratios 0.1,1,10,100,1e6 --paper-scenes grid \
		--out $(OUT)/lattice-zeta0.015
	$(VENV)/bin/pillar-xval lattice --surface-fractions 0.03,0.1 --ratios 0.1,1,10,100,1e6 \
		--paper-scenes grid --out $(OUT)/lattice-substrates

# The floor between the pillars: the elastic-pillar bem-fft against fem-axisym (one pillar)
# and fem-3d (four lattices, Phi 0.03 to 0.4, E_p/E_l 0.1, 1, 1e6) past the pillar tops, on
# F_T, the floor's share, the floor area and the onset, targets judged; $(OUT)/floor-check/
# floor_check.md (about 35 minutes on 2 cores, fem-3d at ~5 GiB on its largest case; resumes).
study-floor: $(STAMP)
	$(VENV)/bin/pillar-xval floor-check --out $(OUT)/floor-check

# The paper's Figs. 3-8 (PNG + CSV each), figures.md and timing.json in $(OUT)/figures; about
# 900 scenes and 400 bisection solves, a few minutes on 2 cores (resumes after an interruption).
figures: $(STAMP)
	$(VENV)/bin/pillar-xval figures --out $(OUT)/figures

# One pytest-xdist worker per CPU this process may use (tests/conftest.py counts them from
# the affinity mask and the cgroup quota, as the solvers' threads do).
test: $(STAMP)
	$(PY) -m pytest -q -n auto

# The documentation site in docs/_build/html, warnings as errors; every figure of the
# tutorials is drawn by its code as the site is built.  tests/test_docs.py builds it too.
docs: $(STAMP)
	$(VENV)/bin/sphinx-build -W --keep-going -b html docs docs/_build/html

# ruff (the rules in pyproject.toml) and mypy on the solver packages' public modules;
# tests/test_lint.py runs both inside make test.
lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

# Byte-for-byte reproduction against another revision (AGAINST, default main): the figures'
# data (quick), a four-scene lattice study and the planner's lattice tables from it, each side
# in its own interpreters with its own pillar-compliance cache (about 5 minutes on 2 cores);
# $(OUT)/reproduce/reproduce.json lists what reproduced.  FULL=1: the full figures (minutes).
AGAINST ?= main
reproduce: $(STAMP)
	rm -rf $(OUT)/reproduce
	$(PY) -m validation.reproduce --against $(AGAINST) --out $(OUT)/reproduce $(if $(FULL),--full)

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench-bem: $(STAMP)
	$(PY) -m validation.bench.bem --out $(OUT)/bench-bem
	$(MAKE) bench-fft

# FFT BEM against its floor (the bare FFT pair on its padded grid) and ContactMechanics (the
# optional [bench] extra) on the same grid, 3e5 and 1e6 cells, rigid and Hooke pillars, medians
# of 3 interleaved runs: the table in $(OUT)/bench-fft/bench_fft.md (about 30 minutes, most of
# it ContactMechanics at 1e6 cells).
bench-fft: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]' || echo "bench-fft: ContactMechanics not installed; the comparison will be skipped"
	$(PY) -m validation.bench.fft --out $(OUT)/bench-fft

# The floor between the pillars in bem-fft: a mixed against a suspended solve on one grid
# (~1e6 cells, medians of 3 alternate runs), iterations against the floor's share, the floor
# quantities' order and GCI over N = 8-64, and ContactMechanics (the [bench] extra) with the
# floor in its topography on two scenes: $(OUT)/bench-floor/bench_floor.md (about 15 minutes).
bench-floor: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]' || echo "bench-floor: ContactMechanics not installed; the comparison will be skipped"
	$(PY) -m validation.bench.floor --out $(OUT)/bench-floor

# Where the elastic BEM's floor area parts from fem-3d on dense lattices, by parts: the BEM's
# ladder and a floor-only gap offset, the floor's excess coupling beside one bonded pillar
# (Fourier FEM), the BEM with it, fem-3d with its floor disk refined alone, fem-3d's ladders
# with the patch-sized floor and with the contact-size one (judged as the floor-check does):
# $(OUT)/bench-floor-gap/bench_floor_gap.md (about 70 minutes; fem-3d peaks at 12 GiB).
bench-floor-gap: $(STAMP)
	$(PY) -m validation.bench.floor_gap --out $(OUT)/bench-floor-gap

# Study engine: a sweep killed (kill -9) mid-way and resumed loses and repeats nothing; the
# same sweep on a Dask scheduler + two worker processes (127.0.0.1) gives the pool's table.
# FFT BEM on the GPU against the CPU path in one run (needs the [gpu] extra and a GPU; without
# one it runs the CPU column on small levels and says the GPU column is pending).
bench-gpu: $(STAMP)
	$(PY) -m validation.bench.gpu --out $(OUT)/bench-gpu

# 3D FEM: unknowns, time by phase, iterations and peak memory over a mesh_size ladder on
# Phi = 0.2 and on the densest paper scene (about 12 minutes).
bench-fem3d: $(STAMP)
	$(PY) -m validation.bench.fem3d --out $(OUT)/bench-fem3d --levels 2.83,2,1.41 --dense 2.83,2,1.41

# The elastic-pillar BEM's cost against fem-3d at equal accuracy: Phi = 0.2
# and 0.82, fem-3d at mesh_size 2.83, 2, 1.41 (its Richardson estimate the reference), the FFT
# and dense BEMs with Hooke and elastic pillars, the compliance build uncached; the table and
# the claims in $(OUT)/bench-elastic/elastic_fem3d.md (30-60 minutes; resumes).
bench-elastic: $(STAMP)
	$(PY) -m validation.bench.elastic_fem3d --out $(OUT)/bench-elastic

# Force control against indentation control at the same resolution, timed alternately in one
# run: paper-fig3-dense with bem-fft (N = 32, 64), bem (P = 11) and fem-3d (mesh_size 2.83, 2,
# 1.41), single-pillar with fem-axisym (mesh_size 2, 1, 0.5); the table in
# $(OUT)/bench-force/bench_force.md (about 30 minutes, most of it fem-3d at 1.41).
bench-force: $(STAMP)
	$(PY) -m validation.bench.force --out $(OUT)/bench-force

# fem-3d with the floor against suspended runs at the same mesh size (time, phases, memory).
bench-fem3d-floor: $(STAMP)
	$(PY) -m validation.bench.fem3d_floor --out $(OUT)/bench-fem3d-floor --repeats 3

# fem-3d's floor on the floor validation's two dense lattices (Phi 0.2, 0.4) at its three
# levels, this checkout against BASELINE, a checkout of the old code (git archive REV | tar -x
# -C DIR): elements, peak memory, phases and the floor's contact area, the runs interleaved
# (about 25 minutes on 2 shared cores, 12 GiB at its peak).
bench-fem3d-floor-levels: $(STAMP)
	$(if $(BASELINE),,$(error BASELINE=DIR: a checkout of the code to compare against))
	$(PY) -m validation.bench.ab --baseline $(BASELINE) --out $(OUT)/bench-fem3d-floor-levels \
		--repeats 1 $(foreach p,0.2 0.4,$(foreach m,2.83 2 1.41,--case floor3d:$(p):$(m)))

# The floor benchmark's timed scene with the floor touched (floor:1) and suspended (floor:20),
# this checkout against BASELINE (as above), in rounds of both: each side's ratio of their
# medians, under one load (7 fresh interpreters a side and case, about 5 minutes on 2 cores).
bench-floor-ab: $(STAMP)
	$(if $(BASELINE),,$(error BASELINE=DIR: a checkout of the code to compare against))
	$(PY) -m validation.bench.ab --baseline $(BASELINE) --out $(OUT)/bench-floor-ab \
		--rounds --repeats 7 --case floor:1 --case floor:20

# fem-3d's mesh phase alone (gmsh and the scikit-fem mesh) at the lattice study's levels
# 2.83 and 2 on Phi = 0.2 and 0.82, this checkout against BASELINE (as above): CPU and wall
# medians of 4 interleaved runs, elements, quality and whether both made the same mesh (a
# few minutes).
bench-mesh3d-ab: $(STAMP)
	$(if $(BASELINE),,$(error BASELINE=DIR: a checkout of the code to compare against))
	$(PY) -m validation.bench.mesh3d_ab --baseline $(BASELINE) --out $(OUT)/bench-mesh3d-ab

# fem-3d's assemble phase alone against a checkout BASELINE=DIR, interleaved, on one core and
# one thread (a lattice study's case): CPU time (user, system), the phase's own peak memory,
# and whether both built the same matrix bit for bit (about 5 minutes).
bench-assembly3d-ab: $(STAMP)
	$(if $(BASELINE),,$(error BASELINE=DIR: a checkout of the code to compare against))
	PILLAR_XVAL_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
	taskset -c $$($(PY) -c "import os; print(min(os.sched_getaffinity(0)))") \
	$(PY) -m validation.bench.assembly3d_ab --baseline $(BASELINE) --out $(OUT)/bench-assembly3d-ab

# Thread scaling: bem-fft at 1e6 cells and the dense BEM on 1 up to the CPUs this process may
# use (fresh interpreters, medians of 3 interleaved runs, answers compared with 1 thread's),
# and the FFT iteration's CPU split against the float64 pair at 3e5 and 1e6 cells (a few
# minutes; THREADS=1,2,4,8,16 and CASES=fft,dense,fem3d for a larger machine; CASES= for the
# split alone; BASELINE=DIR, another checkout, splits its iteration too, interleaved).
THREADS ?=
CASES ?= fft,dense
BASELINE ?=
bench-threads: $(STAMP)
	$(PY) -m validation.bench.threads --out $(OUT)/bench-threads --cases "$(CASES)" \
		$(if $(THREADS),--threads $(THREADS),) $(if $(BASELINE),--baseline $(BASELINE),)

# The planner's predicted over measured seconds of bem-fft and dense bem solves at 1 and all
# the CPUs (THREADS=1,4,16 to choose), this machine calibrated afresh at each count.
bench-planner-threads: $(STAMP)
	$(PY) -m validation.bench.planner_threads --out $(OUT)/bench-planner-threads \
		$(if $(THREADS),--threads $(THREADS),)

# The kit that lets a lent machine without gmsh or MKL run fem-3d (validation/bench/lent_kit.py,
# docs/performance.md): two xz archives in .lent/, 40.5 and 53.0 MiB (about 20 minutes).
lent-kit: $(STAMP)
	$(PY) -m validation.bench.lent_kit build --venv $(VENV) --out .lent

# CLI start-up: `pillar-xval --version` and `solve --help`, median of 5 fresh processes each.
bench-startup: $(STAMP)
	$(PY) -m validation.bench.startup --out $(OUT)/bench-startup

# Sweep grids before any solve: the dry run's time at 1e4 and 1e5 points, the memory per axis
# value and per case of a run (the sizes a grid is checked against; seconds).
bench-sweep: $(STAMP)
	$(PY) -m validation.bench.sweep --out $(OUT)/bench-sweep

bench-engine: $(STAMP)
	$(PY) -m validation.bench.engine --out $(OUT)/bench-engine

# Figures: error of the figures' resolution against a finer reference on a seeded sample of
# their scenes, and the whole figure set timed in a fresh folder (bench_figures.json).
bench-figures: $(STAMP)
	$(PY) -m validation.bench.figures --out $(OUT)/bench-figures

# The planner's error and cost models, measured (convergence ladders, Gecit grid at four
# indentations, closed forms, FEM truncation, the lattice study's Hooke error; resumable; about
# 2 h, 1.5 of them the lattice study, 10 minutes the rest on a fresh cache) and installed as the
# package's data (validation/planner/data/*.json).
# The lattice studies calibrate reads, comma-separated (the first holds a shared scene).
empty :=
comma := ,
LATTICE_STUDIES = $(subst $(empty) $(empty),$(comma),$(foreach s,lattice lattice-substrates \
	lattice-zeta0.05 lattice-zeta0.015,$(OUT)/$(s)/lattice.json))
calibrate: study-lattice
	$(VENV)/bin/pillar-xval calibrate --out $(OUT)/calibrate \
		--lattice $(LATTICE_STUDIES) --install

# The planner validated on 60 seeded scenes it never saw, 15 of them lattices with sigma0
# requested judged against fem-3d with every candidate (--scenes, --lattice-scenes, --seed;
# --dry-run prints the estimated time only; resumable; about 16 minutes of solves by the
# planner's estimate, 8-9 minutes on this 2-core machine).
validate-planner: $(STAMP)
	$(VENV)/bin/pillar-xval validate-plan --out $(OUT)/validate-plan

# Every model over the corners and edges of the parameter space: table and heat map.
extremes: $(STAMP)
	$(VENV)/bin/pillar-xval extremes --out $(OUT)/extremes

# Which model the planner picks over Phi x zeta/h, with the Hooke sigma0 error's contours.
regimes: $(STAMP)
	$(VENV)/bin/pillar-xval regimes --out $(OUT)/regimes

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache docs/_build docs/generated docs/_tables
