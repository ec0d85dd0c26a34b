# rivercal — the two commands: `make demo` and `make test` (both set up .venv themselves); `make check` is the
# developer's quick loop (the unit tier alone).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= out/demo

.PHONY: demo test check test-fast bench lint docs venv clean clean-cache browser postgres kernels

# The compiled time loop is kept in ~/.cache/rivercal/kernels, one folder per version of the kernels' sources
# (rivercal/_kernel_cache.py): after a change of a kernel it is compiled again, once (about a
# minute), instead of in every process that runs the engine first; a fresh clone of a version this machine has
# compiled loads it in seconds. Machine code that numba kept beside the sources (where the user's cache could
# not be written) notices only a change of a kernel's own file, not of one it inlines: it is dropped here.
KERNEL_SOURCES := $(shell find src/rivercal/engine -name '*.py' | sort)
KERNEL_STAMP := $(VENV)/.kernels

# The dashboard tests drive Debian's chromium through chromedriver (never a downloaded browser).
CHROMIUM := /usr/bin/chromium
CHROMEDRIVER := /usr/bin/chromedriver

# uv installs the packages in parallel (the dev extra in 9 s on two cores once its cache holds them); where
# uv cannot, pip does.
# Bytecode: an environment with PYTHONDONTWRITEBYTECODE set would have every process (each test's subprocess,
# each evaluation worker) compile the libraries' modules and rivercal's own again (0.3 s for rivercal alone,
# measured). The commands below run without it, so the first import of a module writes its bytecode and
# later processes load it; compiling the whole environment at install instead took 37 s, mostly for modules
# no command imports.
WRITE_BYTECODE := env -u PYTHONDONTWRITEBYTECODE

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "rivercal needs Python >= 3.11 (found " + sys.version.split()[0] + "); set PYTHON=python3.11")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	{ $(PY) -m pip install --quiet uv && $(PY) -m uv pip install --quiet --python $(PY) -e ".[dev]"; } \
		|| $(PY) -m pip install --quiet -e ".[dev]"
	@touch $(STAMP)

venv: $(STAMP)

$(KERNEL_STAMP): $(KERNEL_SOURCES) | $(STAMP)
	@find src -name '*.nbi' -delete -o -name '*.nbc' -delete
	@echo "compiling the engine's time loop (for a version of the engine new to this machine: about a minute, once)"
	$(WRITE_BYTECODE) $(VENV)/bin/rivercal compile
	@touch $(KERNEL_STAMP)

kernels: $(KERNEL_STAMP)

demo: $(STAMP) kernels
	$(WRITE_BYTECODE) $(VENV)/bin/rivercal demo --out $(OUT)

$(CHROMIUM) $(CHROMEDRIVER):
	@command -v apt-get >/dev/null || { echo "make test needs Debian's chromium and chromium-driver (apt-get)"; exit 1; }
	apt-get update -qq
	DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium chromium-driver

browser: $(CHROMIUM) $(CHROMEDRIVER)

# The PostgreSQL store's tests start a real server (initdb/pg_ctl of Debian's postgresql package) in a
# temporary folder; nothing is configured system-wide.
postgres:
	@command -v initdb >/dev/null 2>&1 || ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || { \
		command -v apt-get >/dev/null || { echo "make test needs Debian's postgresql package (apt-get)"; exit 1; }; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends postgresql; }

# Distribution over the workers: whole modules, in the order tests/conftest.py gives (the longest first), each to
# the first free worker. A module's shared fixtures (a documentation build, a reference replay, an imported
# model, a twin's truth) are then made once in the run: work stealing split modules wherever it cut the queues,
# and the worker that took part of a module made its fixtures again.
DIST := --dist loadfile --no-loadscope-reorder

test: $(STAMP) kernels browser postgres
	$(WRITE_BYTECODE) $(PY) -m pytest -n auto $(DIST) -q --durations=25

# The developer's loop: the unit tier alone (tests/unit: no process, no server, no network; its conftest enforces
# it), so it needs no system package (no chromium, no PostgreSQL) and only the compiled kernels; its few tests
# marked slow (longer than about 10 s each) are left to make test.
check: $(STAMP) kernels
	$(WRITE_BYTECODE) $(PY) -m pytest tests/unit -n auto $(DIST) -q -p no:cacheprovider -m "not slow"

test-fast: $(STAMP) kernels browser postgres
	$(WRITE_BYTECODE) $(PY) -m pytest -n auto $(DIST) -q -m "not slow"

bench: $(STAMP) kernels browser
	@mkdir -p out/bench
	$(WRITE_BYTECODE) $(PY) benchmarks/run_all.py --out out/bench

# The documentation site: docs/ -> docs/_build/html (warnings are errors; the tutorial is executed).
docs: $(STAMP) kernels
	$(WRITE_BYTECODE) $(VENV)/bin/sphinx-build -b html -E -W --keep-going -q docs docs/_build/html
	@echo "the documentation: docs/_build/html/index.html"

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks scripts docs
	$(VENV)/bin/lint-imports

clean-cache:
	find src -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -rf "$${XDG_CACHE_HOME:-$$HOME/.cache}/rivercal/kernels"

clean: clean-cache
	rm -rf $(VENV) out .pytest_cache .ruff_cache docs/_build docs/tutorial docs/reference/api docs/reference/generated
