# Every target sets itself up: only python3 and the package registries are needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test test-all bench lint sample-data clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(VENV)/.installed: $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q -e .
	touch $@

$(VENV)/.test-installed: $(VENV)/.installed
	$(BIN)/python -m pip install -q -e ".[test]"
	touch $@

demo: $(VENV)/.installed
	@echo "== before: markers with gaps in sample_data/walk_gapped.csv"
	$(BIN)/mocapfill info --gaps-only sample_data/walk_gapped.csv
	@echo "== repair (default method: trnn)"
	$(BIN)/mocapfill repair sample_data/walk_gapped.csv $(VENV)/walk_repaired.csv
	@echo "== after"
	$(BIN)/mocapfill info --gaps-only $(VENV)/walk_repaired.csv
	@echo "== error against the gap-free truth: trnn, then linear interpolation for comparison"
	$(BIN)/mocapfill score sample_data/walk_truth.csv $(VENV)/walk_repaired.csv --gapped sample_data/walk_gapped.csv
	@$(BIN)/mocapfill repair sample_data/walk_gapped.csv $(VENV)/walk_linear.csv --method linear 2>/dev/null
	$(BIN)/mocapfill score sample_data/walk_truth.csv $(VENV)/walk_linear.csv --gapped sample_data/walk_gapped.csv

test: $(VENV)/.test-installed
	$(BIN)/python -m pytest -m "not slow" -q

test-all: $(VENV)/.test-installed
	$(BIN)/python -m pytest -q

bench: $(VENV)/.installed
	$(BIN)/mocapfill bench speed

sample-data: $(VENV)/.installed
	$(BIN)/python scripts/make_sample_data.py sample_data

lint: $(VENV)/.test-installed
	$(BIN)/python -m pip install -q ruff
	$(BIN)/python -m ruff check mocapfill tests

clean:
	rm -rf $(VENV) build *.egg-info
