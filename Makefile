# rivercal — the two commands: `make demo` and `make test` (both set up .venv themselves).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= out/demo

.PHONY: demo test test-fast bench lint venv clean clean-cache

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "rivercal needs Python >= 3.11 (found " + sys.version.split()[0] + "); set PYTHON=python3.11")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	@touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/rivercal demo --out $(OUT)

test: $(STAMP)
	$(PY) -m pytest -n auto -q

test-fast: $(STAMP)
	$(PY) -m pytest -n auto -q -m "not slow"

bench: $(STAMP)
	@mkdir -p out/bench
	$(PY) benchmarks/run_all.py --out out/bench

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks scripts
	$(VENV)/bin/lint-imports

clean-cache:
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete

clean: clean-cache
	rm -rf $(VENV) out .pytest_cache .ruff_cache
