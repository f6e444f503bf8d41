# Set-up is part of every target: a fresh clone needs only `make demo` or `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: demo study-gecit test test-slow bench-bem bench-fft bench-gpu bench-fem3d bench-engine clean \
	calibrate validate-planner extremes

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]' --config-settings editable_mode=compat
	touch $(STAMP)

# The main job: BEM (Hooke pillar) against FEM (elastic pillar) on the single-pillar and Hertz
# scenes, then the paper's Fig. 3 scenes with the BEM.
demo: $(STAMP)
	$(VENV)/bin/pillar-xval compare --scene single-pillar --out $(OUT)/compare-single-pillar
	$(VENV)/bin/pillar-xval compare --scene hertz --out $(OUT)/compare-hertz
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-sparse --out $(OUT)/fig3-sparse
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-dense --out $(OUT)/fig3-dense

# The Gecit-like study: Hooke-spring BEM against the elastic-pillar FEM over E_p/E_l and h/d
# (a few minutes; resumes after an interruption).
study-gecit: $(STAMP)
	$(VENV)/bin/pillar-xval gecit --out $(OUT)/gecit

test: $(STAMP)
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench-bem: $(STAMP)
	$(PY) -m validation.bench.bem --out $(OUT)/bench-bem
	$(MAKE) bench-fft

# FFT BEM: cells vs time vs memory, and ContactMechanics side by side (optional extra).
bench-fft: $(STAMP)
	$(PY) -m pip install --quiet -e '.[bench]' || echo "bench-fft: ContactMechanics not installed; the comparison will be skipped"
	$(PY) -m validation.bench.fft --out $(OUT)/bench-fft

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

bench-engine: $(STAMP)
	$(PY) -m validation.bench.engine --out $(OUT)/bench-engine

# The planner's error and cost models, measured (convergence ladders, Gecit grid, closed forms,
# FEM truncation; resumable) and installed as the package's data (validation/data/*.json).
calibrate: $(STAMP)
	$(VENV)/bin/pillar-xval calibrate --out $(OUT)/calibrate --install

# The planner validated on 60 seeded scenes it never saw (resumable; about half an hour).
validate-planner: $(STAMP)
	$(VENV)/bin/pillar-xval validate-plan --out $(OUT)/validate-plan

# Every model over the corners and edges of the parameter space: table and heat map.
extremes: $(STAMP)
	$(VENV)/bin/pillar-xval extremes --out $(OUT)/extremes

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
