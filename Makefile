# Two commands take a fresh machine to a finished run and a green test suite:
#   make demo   -> virtual env, install, FMU build, default scenario, CSV + PNG
#   make test   -> virtual env, install, FMU build, pytest (long campaigns excluded)
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
DEMO_SCENARIO ?= scenarios/keio_fig7_aluminium_force_control.toml
DEMO_OUT      ?= results/demo

.PHONY: all venv fmus demo test test-long bench wheel clean

all: test

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]"
	touch $@

venv: $(VENV)/.installed

fmus: $(VENV)/.installed
	$(PY) -m drillcosim.build

demo: fmus
	$(VENV)/bin/drillcosim run $(DEMO_SCENARIO) --out $(DEMO_OUT)

# two processes, a test file each at a time (module fixtures are shared within a file; the
# heaviest files first: tests/conftest.py). Bytecode is written even where the environment sets
# PYTHONDONTWRITEBYTECODE: else each worker and each subprocess a test starts compiles every
# module (and pytest rewrites every test file) again, ~6 s of CPU per process
test: fmus
	PYTHONDONTWRITEBYTECODE= $(PY) -m pytest -q -n 2 --dist loadfile

test-long: fmus
	$(PY) -m pytest -q -m long

bench: fmus
	$(PY) -m benchmarks

# the wheel from the package sources only: setuptools copies into build/lib and never
# removes a stale file there, so a used checkout's build/ goes first (pyproject.toml:
# package-data names the sources; the plant FMUs are built on first use)
wheel: $(VENV)/.installed
	rm -rf build
	$(PY) -m pip wheel . --no-deps -q -w dist

clean:
	rm -rf fmus/build results .pytest_cache
