# The two commands of the README: `make bench` (the main job) and `make test` (what CI runs: `make lint`,
# `make typecheck`, `make docs`, then pytest without the slow tests; `make test-all` runs them too).
# Both create .venv, install the CPU build of PyTorch from the pinned file
# first (an unpinned torch pulls gigabytes of CUDA packages), then the project,
# then compile its numba kernels once (python -m vcnc_gym.warmup: the envs'; python -m vcnc_bench.warmup: the
# controllers' laws the main job runs).
PYTHON ?= python3
VENV ?= .venv
# numpy's AVX-512 kernels (X86_V4) round sin, cos and exp differently in the last bit from its AVX2 ones: the
# references, and with them the keys of the shipped commissioning runs and floors, would then differ by host.  Both
# commands run numpy on its AVX2 kernels on every x86 host, as the shipped files were made (a host without
# AVX-512 is unchanged); set NPY_DISABLE_CPU_FEATURES= (empty) to run numpy's fastest kernels instead.
export NPY_DISABLE_CPU_FEATURES ?= X86_V4 AVX512_ICL AVX512_SPR
BIN := $(VENV)/bin

.PHONY: install test test-all bench lint typecheck docs

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

# What the main job needs (the controllers, the agents, G-code), then the kernels compiled once; `make test` adds
# the development tools on top (pytest, the docs, the sweeps' Ray, the Zoo: about half of a fresh install's time).
$(VENV)/.installed-run: pyproject.toml | $(BIN)/python
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e ".[baselines,agents,gcode]"
	$(BIN)/python -m vcnc_gym.warmup
	$(BIN)/python -m vcnc_bench.warmup
	touch $@

$(VENV)/.installed: $(VENV)/.installed-run
	$(BIN)/pip install -q -e ".[dev]"
	touch $@

install: $(VENV)/.installed

lint: install
	$(BIN)/ruff check --no-cache .
	$(BIN)/ruff format --check --no-cache .

# pyright in basic mode on vcnc_gym and the public faces of the other packages ([tool.pyright] in pyproject.toml,
# typecheck/README.md); offline: the dev extra's pyright[nodejs] brings its own Node.js.
typecheck: install
	$(BIN)/pyright --pythonpath $(BIN)/python

# The documentation site (docs/), warnings as errors, no network: docs/_build/html/index.html
docs: install
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html

# CI runs `make test`: lint, the type check, the docs build and every test but those marked slow (> 10 s each on 2 cores;
# tests/conftest.py), which keeps the whole CI run well under 15 minutes.  `make test-all` runs them too.
# The tests run on 2 processes (pytest-xdist), each test file on one of them (--dist loadfile: a module's shared
# fixtures are built once); the 15 slowest tests are listed at the end, to keep the CI run in its budget.
test: lint typecheck docs
	$(BIN)/python -m pytest -q -m "not slow" -n 2 --dist loadfile --durations=15

test-all: lint typecheck docs
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# The main job: the default table (vcnc_bench.cli.DEFAULT_IDS) on the idle cores, its JSON and plots in bench-out/.
# `vcnc-bench --all` runs every id and every policy; `vcnc-bench --plants N` the uncertainty box.
bench: $(VENV)/.installed-run
	rm -f bench-out/bench.json
	$(BIN)/vcnc-bench --json bench-out/bench.json --plots bench-out --leaderboard bench-out/leaderboard.md
	$(BIN)/python -m vcnc_bench.check --default bench-out/bench.json
