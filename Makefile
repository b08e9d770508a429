# The two commands of the README quick start. Both create .venv and install what they need.
#   make demo   - run the main job on defaults
#   make test   - run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
# torch is pinned: this machine's pip finds a CPU build of 2.13.0; a bare `torch` pulls a CUDA build.
TORCH := torch==2.13.0
# The suite runs on one pytest-xdist worker per CPU, at most 4 (on the 2-core CI machine it takes ~10 min
# this way, ~17-21 min on one worker); tests are independent, each in its own tmp_path.
TEST_WORKERS := $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( n < 4 ? n : 4 )))

.PHONY: demo test install clean-venv

$(VENV)/.installed: setup.cfg pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet $(TORCH)
	$(PIP) install --quiet -e ".[test,tutorials]" $(TORCH)
	touch $@

install: $(VENV)/.installed

demo: install
	$(VENV)/bin/dexart-lite demo

test: install
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal

clean-venv:
	rm -rf $(VENV)
