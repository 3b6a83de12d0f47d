# The two commands of the README, each doing its own set-up on a fresh machine:
#   make square   -> runs the main job (the 1 m square experiment)
#   make test     -> runs the test suite
# The set-up creates .venv, installs the CPU build of PyTorch first (so that
# stable-baselines3 does not pull a CUDA build), then the project with its
# training, development, TorchRL, documentation, Ray (sweeps, RLlib) and pose-graph
# (GTSAM) extras, and compiles the kernels once (moma-env warm-up), so that the first
# env, experiment or test does not wait for them. Override TORCH to use another build.

PYTHON ?= python3
VENV ?= .venv
TORCH ?= torch==2.13.0
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup square test

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet "$(TORCH)"
	$(BIN)/python -m pip install --quiet -e ".[train,dev,torchrl,docs,ray,graph]"
	$(BIN)/moma-env warm-up
	touch $(STAMP)

square: $(STAMP)
	$(BIN)/moma-env experiment square --out runs/square

# -n auto: pytest-xdist runs the suite on every core, at most 8 processes (the tests are
# independent and write only to their own temporary folders); --dist loadgroup keeps the
# tests of one xdist_group (those of the session's Ray) on one process, so one Ray starts.
test: $(STAMP)
	$(BIN)/python -m pytest -n auto --maxprocesses 8 --dist loadgroup
