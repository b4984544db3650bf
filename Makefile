# Two entry points; both create / reuse .venv and install the pinned versions first.
#   make demo   the Prefect pipeline on PickCube (collect -> mimic -> train -> evaluate) on the CPU
#   make test   run the test suite (real Newton physics on CPU Warp)
PY ?= python3
VENV := .venv
STAMP := $(VENV)/.installed

$(STAMP): pyproject.toml setup.py
	$(PY) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q torch==2.13.0
	$(VENV)/bin/pip install -q -e '.[test]'
	touch $(STAMP)

.PHONY: demo test bench
demo: $(STAMP)
	$(VENV)/bin/newton-lab pipeline --task GalbotG1-PickCube-v0 --device cpu --out outputs/demo

test: $(STAMP)
	$(VENV)/bin/python -m pytest -q

bench: $(STAMP)
	$(VENV)/bin/newton-lab bench --task GalbotG1-PickCube-v0 --num-envs 4 --steps 200 --device cpu
