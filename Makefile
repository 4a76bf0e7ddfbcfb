# vei: every target sets itself up on a fresh machine (python3 >= 3.11 and the package registries).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
# Separate tool environment for the ASAM Quality Checker (it pins numpy < 2).
QC_VENV  := .tools/qc
QC_STAMP := $(QC_VENV)/.installed-stamp
DEMO_OUT ?= demo-out
# CommonRoad (vei export commonroad; docs/commonroad.md), without their protobuf pin.
COMMONROAD := 'commonroad-io==2024.3' 'commonroad-vehicle-models==3.0.2' 'commonroad-drivability-checker==2025.4.0'
# Argoverse 2 (vei import tracks --format av2; docs/datasets.md), without torch & co.
AV2 := 'av2==0.3.6'

# Test workers (pytest-xdist): one per core; `make test PYTEST_WORKERS=0` runs in one process.
PYTEST_WORKERS ?= auto
PYTEST := MPLBACKEND=Agg VEI_QC_BIN=$(CURDIR)/$(QC_VENV)/bin $(VENV)/bin/pytest -q -n $(PYTEST_WORKERS)

.PHONY: demo test test-slow test-all bench lint format venv qc-tools clean

$(STAMP): pyproject.toml Makefile
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[all,bench,dev]'
	$(PY) -m pip install --quiet --no-deps $(COMMONROAD)
	$(PY) -m pip install --quiet --no-deps $(AV2)
	touch $(STAMP)

venv: $(STAMP)

$(QC_STAMP):
	$(PYTHON) -m venv $(QC_VENV)
	$(QC_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(QC_VENV)/bin/python -m pip install --quiet 'asam-qc-openscenarioxml==1.0.0' 'asam-qc-opendrive==1.0.0'
	touch $(QC_STAMP)

qc-tools: $(QC_STAMP)

demo: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/vei demo --out $(DEMO_OUT)

# The fast tier (docs/testing.md): everything not marked slow.
test: $(STAMP) $(QC_STAMP)
	$(PYTEST) -m "not slow"

# The slow tier alone: whole-dataset, Ray, README-command, esmini and browser tests.
test-slow: $(STAMP) $(QC_STAMP)
	$(PYTEST) -m slow

# Both tiers: the whole suite (what .ci/run calls).
test-all: $(STAMP) $(QC_STAMP)
	$(PYTEST)

bench: $(STAMP)
	MPLBACKEND=Agg $(PY) -m benchmarks

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/ruff format --check src tests benchmarks

format: $(STAMP)
	$(VENV)/bin/ruff check --fix src tests benchmarks
	$(VENV)/bin/ruff format src tests benchmarks

clean:
	rm -rf $(VENV) .tools $(DEMO_OUT) .pytest_cache .ruff_cache
