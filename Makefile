# lookahead_control: `make demo` and `make test` set everything up on a fresh machine.
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
EXES_DIR := $(VENV)/lib/lookahead_control
# Unique DDS domain per make invocation; loopback discovery only.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: all venv demo test lint fuzz bench compare clean

all: test

# Re-installs only when the pins (requirements.lock) or the entry points (setup.py) change.
$(STAMP): requirements.lock setup.py setup.cfg
	@command -v $(PYTHON) >/dev/null || { echo "make: $(PYTHON) not found: install Python 3.11"; exit 1; }
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.lock
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	@# setup.cfg puts executables where `ros2 run` looks (<prefix>/lib/lookahead_control);
	@# link them into the venv's bin too so they are on PATH after `source .venv/bin/activate`.
	@for exe in $(EXES_DIR)/*; do ln -sf "$$(realpath $$exe)" $(VENV)/bin/; done
	@touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/demo --out bags/demo

# Three pytest-xdist workers on the CI machine's two cores: the process tests wait on
# discovery and on their nodes, and a third worker runs in those waits (measured idle on
# one 2-core machine: 984 s with two, 863 s with three). Each test file on one worker
# (module fixtures run once); TEST_WORKERS=0 runs in one process.
TEST_WORKERS ?= 3
test: $(STAMP)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile --durations=15

fuzz: $(STAMP)
	FUZZ_EXAMPLES=100000 $(PY) -m pytest -q -s test/test_fuzz.py

# Benchmarks (not part of `make test`): bench/results/*.json and a table; about 20 min.
bench: $(STAMP)
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-$$(( $$$$ % 100 + 1 ))} $(PY) -m bench.run $(BENCH_ARGS)

# League table of every law (docs/baselines.md): bags/compare/league.{md,csv,png}; about 8-9 min on an idle 2-core machine (estimated).
compare: $(STAMP)
	$(VENV)/bin/compare --out bags/compare $(COMPARE_ARGS)

lint: $(STAMP)
	$(PY) -m pytest -m lint

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache
