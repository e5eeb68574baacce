# Two entry points (README quickstart): `make run` sets up and flies the main job, `make test` sets up and tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
# Rerun sink for `make run`: spawn a viewer when a display is present, else record a file.
RERUN ?= $(if $(DISPLAY)$(WAYLAND_DISPLAY),spawn,save:out/square/run.rrd)
ARGS ?=
# Python may cache its compiled modules (some machines turn that off): every process a test starts, and every test run
# after the first, then skips compiling rov_mav, sim_bridge and the rewritten tests again.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: setup run test test-fast docs bench bench-tune bench-particles reproduce clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

setup: $(STAMP)

run: setup
	$(BIN)/rov-mav run missions/square.yaml --metrics out/square/metrics.json --log out/square/log \
		--rerun $(RERUN) $(ARGS)

# The whole suite on two workers (pytest-xdist), handed out two tests at a time in the collection's order (the process
# tests first: tests/conftest.py): every end-to-end test holds its checks with another test beside it.
test: setup
	$(BIN)/python -m pytest -q -n 2 --maxschedchunk 2

# The tests that start no process and no bridge (tests/conftest.py's `process` marker): the physics, the math, the
# readers; for the loop of a change. `make test` (what CI runs) is the whole suite.
test-fast: setup
	$(BIN)/python -m pytest -q -m "not process" -n 2 --dist loadgroup

docs: setup
	$(BIN)/sphinx-build -W --keep-going -n -q -b html docs docs/_build/html
	@echo "the manual: docs/_build/html/index.html"

bench: setup
	$(BIN)/python tools/bench_simulation.py
	$(BIN)/python tools/bench_telemetry.py

bench-tune: setup
	$(BIN)/python -m pip install --quiet -e ".[bench]"
	$(BIN)/python tools/bench_tune.py

bench-particles: setup
	nice $(BIN)/python tools/bench_particles.py

reproduce: setup
	$(BIN)/python tools/reproduce_report.py

clean:
	rm -rf $(VENV) out .pytest_cache docs/_build
