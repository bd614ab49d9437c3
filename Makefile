# Two entry points for a fresh machine:  `make run`  and  `make test`.
# Both create .venv (once, or again when pyproject.toml changes) and install the bench into it,
# with its test extra (pytest, Hypothesis, nbformat): `make run` and `make test` share one .venv.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test test-all bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/cosim run crank_rocker_373rpm

test: $(STAMP)
	$(BIN)/python -m pytest

test-all: $(STAMP)
	$(BIN)/python -m pytest -m ""

bench: $(STAMP)
	$(BIN)/python -m tests.benchmarks.bench --budget 55

clean:
	rm -rf $(VENV) build *.egg-info
