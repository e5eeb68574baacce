# Two entry points (README quickstart): `make run` sets up and flies the main job, `make test` sets up and tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: setup run test bench reproduce clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

setup: $(STAMP)

run: setup
	$(BIN)/rov-mav simulate missions/square.yaml --out out/square

test: setup
	$(BIN)/python -m pytest -q

bench: setup
	$(BIN)/python tools/bench_simulation.py

reproduce: setup
	$(BIN)/python tools/reproduce_report.py

clean:
	rm -rf $(VENV) out .pytest_cache
