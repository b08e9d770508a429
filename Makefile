# The two commands of the README quick start. Both create .venv and install what they need.
#   make demo   - run the main job on defaults
#   make test   - run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
# torch is pinned: this machine's pip finds a CPU build of 2.13.0; a bare `torch` pulls a CUDA build.
TORCH := torch==2.13.0

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
	$(PY) -m pytest -q

clean-venv:
	rm -rf $(VENV)
