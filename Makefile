# Entry points; each creates / reuses .venv and installs the pinned versions first.
#   make demo   the Prefect pipeline on PickCube (collect -> mimic -> train -> evaluate); CPU, or from pixels on CUDA
#   make test   run the test suite (real Newton physics on CPU Warp)
#   make mutate break each promise on purpose in a scratch copy and check its tests catch it
PY ?= python3
VENV := .venv
STAMP := $(VENV)/.installed

$(STAMP): pyproject.toml setup.py tools/install_venv.sh
	tools/install_venv.sh $(PY) $(VENV)
	touch $(STAMP)

.PHONY: demo test test-all bench docs docs-serve mutate
# demo: the cpu recipe (4 expert demos, 100 Mimic demos, 6000 training steps, 40 evaluation episodes; a state
# policy) or, when torch sees a CUDA device, the gpu recipe on it (a policy from the front camera and
# proprioception). How long each takes: docs/benchmarks.md, from the run records. The run record names this command.
# DEMO_ARGS adds flags, e.g. make demo DEMO_ARGS="--recipe cpu".
DEMO_ARGS ?=
demo: $(STAMP)
	NEWTON_LAB_COMMAND="make demo$(if $(DEMO_ARGS), DEMO_ARGS='$(DEMO_ARGS)')" \
	$(VENV)/bin/newton-lab pipeline --task GalbotG1-PickCube-v0 --out outputs/demo $(DEMO_ARGS)

# Tests run on both cores: one pytest worker per core, each test module kept on one worker (its fixtures build
# envs once), the longest modules handed out first (tests/conftest.py). The project is byte-compiled first: with
# PYTHONDONTWRITEBYTECODE set, each of the suite's ~50 subprocesses would compile it again. TEST_WORKERS=0 runs
# the tests in this process.
# LeRobot's own loader reads the exports in tests/test_lerobot_loader.py, from an overlay venv beside .venv that
# tools/lerobot_env.sh builds (what it holds and why: its header; ~15 s once, then reused); built here first so that
# its line shows in the log (the test builds it too, and fails if it cannot). -rs lists every skipped test.
# The tests marked slow (the crash and interrupt campaigns, the docs' pages and the flows run end to end: each pays
# for processes that import torch and Warp, about half of the suite's time on 2 cores) run in CI (CI=true, as .ci/run
# sets it) and with `make test-all`; a plain `make test` leaves them out.
TEST_WORKERS ?= 2
TEST_SELECT = $(if $(or $(filter true 1 yes TRUE True,$(CI)),$(TEST_ALL)),,-m "not slow")
test: $(STAMP)
	tools/lerobot_env.sh $(VENV)/bin/python .venv-lerobot > /dev/null
	$(VENV)/bin/python -m compileall -q newton_lab kernels tasks flows tests examples > /dev/null
	$(VENV)/bin/python -m pytest -q -rs -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder $(TEST_SELECT)

test-all:
	$(MAKE) test TEST_ALL=1

# mutate: break one promise at a time (tools/mutation_cases.py: a curated list of small patches) in a scratch copy and
# run only the tests that cover it; every mutation must be killed (exit 1 on a survivor). Minutes on 2 CPU cores.
# MUTATE_ARGS adds flags, e.g. make mutate MUTATE_ARGS="--only jog-clip-removed" (--list names them).
MUTATE_ARGS ?=
mutate: $(STAMP)
	$(VENV)/bin/python tools/mutations.py $(MUTATE_ARGS)

bench: $(STAMP)
	$(VENV)/bin/newton-lab bench --task GalbotG1-PickCube-v0 --num-envs 4 --steps 200 --device cpu

# The user guide (mkdocs.yml, docs/): `docs` builds it into site/ and fails on any warning (a broken link, a missing
# page, a docstring mkdocstrings cannot read); `docs-serve` serves it at http://127.0.0.1:8000, rebuilt on edits.
# (NO_MKDOCS_2_WARNING: no banner about MkDocs 2 from Material.)
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

docs-serve: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve
