# Set-up is part of every target: a fresh clone needs only `make demo` or `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: demo test test-slow bench-bem clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]' --config-settings editable_mode=compat
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-sparse --out $(OUT)/fig3-sparse
	$(VENV)/bin/pillar-xval solve --scene paper-fig3-dense --out $(OUT)/fig3-dense

test: $(STAMP)
	$(PY) -m pytest -q

test-slow: $(STAMP)
	$(PY) -m pytest -q -m slow

bench-bem: $(STAMP)
	$(PY) -m validation.bench_bem --out $(OUT)/bench-bem

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
