# Two commands for a fresh machine with Python >= 3.11:
#   make reproduce   install into .venv and run the whole workflow (snakemake -j2)
#   make test        install into .venv (with test extras) and run the test suite
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: reproduce tables test test-all install clean benchmark

# The installer is uv (pinned; faster than pip by about 40 s on a fresh machine). Where uv has no wheel
# for the platform, pip installs instead. --compile-bytecode: the .pyc files are written at install, as
# pip does; without them every job would compile numpy, scipy and snakemake again where
# PYTHONDONTWRITEBYTECODE is set (about 5 s per Snakemake start).
UV_VERSION := 0.13.9

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q uv==$(UV_VERSION) || $(BIN)/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	if [ -x $(BIN)/uv ]; then $(BIN)/uv pip install -q --compile-bytecode --python $(BIN)/python -e ".[test]"; \
	else $(BIN)/python -m pip install -q -e ".[test]"; fi
	$(BIN)/python -m compileall -q src > /dev/null  # the editable package's .pyc files too
	touch $(STAMP)

install: $(STAMP)

# jointid results heal (before Snakemake): stops jobs a killed snakemake left running, removes stale
# temporary files and results that no longer match their provenance sidecars (rebuilt by the run, with
# what depends on them); refuses in one line while a lock is held (docs/workflow.md, "Interrupted runs").
reproduce: $(STAMP)
	$(BIN)/jointid results heal
	$(BIN)/snakemake -j2 --rerun-incomplete

# Tables 1-3 alone (what CI gates): the chain mesh -> DOE -> surface -> identify -> verify -> harmonic
TABLES := results/tables/table1_dynamic_stiffness.csv results/tables/table2_power_off.csv \
          results/tables/table3_power_on.csv
tables: $(STAMP)
	$(BIN)/jointid results heal
	$(BIN)/snakemake -j2 --rerun-incomplete $(TABLES)

# two workers; tests/conftest.py groups the tests that share fixtures and starts the slowest first.
# make test leaves out the tests marked extended (more known-truth cases of checks it makes on fewer);
# make test-all runs every test.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m "not extended"

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

benchmark: $(STAMP)
	$(BIN)/python -m benchmarks

clean:
	rm -rf results logs benchmarks/out .snakemake
