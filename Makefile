# One-command set-up and checks. `make test` creates .venv, installs the project with its test extras and
# the client's npm dependencies, then runs ruff and every test.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP_STAMP := $(VENV)/.installed
NPM_STAMP := node_modules/.installed

.PHONY: setup test lint pytest bench clean

setup: $(PIP_STAMP) $(NPM_STAMP)

$(PIP_STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

$(NPM_STAMP): package.json package-lock.json
	npm ci --no-audit --no-fund --loglevel=error
	touch $@

lint: $(PIP_STAMP)
	$(BIN)/ruff check .

pytest: setup
	$(BIN)/pytest

test: setup lint pytest

bench: setup
	$(BIN)/python benchmarks/bench_corpus.py

clean:
	rm -rf $(VENV) node_modules .pytest_cache .ruff_cache var test-artifacts
