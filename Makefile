# jarvis-pytest: every target installs what it needs by itself.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
JARVIS := $(BIN)/jarvis
AGENT ?= oracle
WORKERS ?= 2
MARKERS ?= ubuntu
PYTEST_ARGS ?=
STAMP := $(VENV)/.installed

.PHONY: setup engine images host-packages test bench clean-devices

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

## setup: create .venv with the package (editable) and its test dependencies
setup: $(STAMP)

## engine: make sure a Docker engine answers (installs Debian's docker.io and starts dockerd when root)
engine: setup
	$(JARVIS) engine ensure

## images: build the device images (only what changed since the last build)
images: engine
	$(JARVIS) images build

## host-packages: Debian packages the tests use on the host (chromium for the dashboard's browser tests)
host-packages:
	@command -v chromium >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get -o DPkg::Lock::Timeout=600 update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -q chromium >/dev/null; \
	  else echo "missing chromium: run  sudo apt-get install -y chromium"; exit 1; fi; }

## test: the project's own tests, container tests included
test: images host-packages
	$(BIN)/pytest -p no:cacheprovider tests -n $(WORKERS) $(PYTEST_ARGS)

## bench: run the benchmark (the Ubuntu tasks; AGENT=oracle by default) and write the tables and a report
bench: images
	$(BIN)/pytest tasks -n $(WORKERS) --agent $(AGENT) -m "$(MARKERS)" $(PYTEST_ARGS)

## clean-devices: remove containers and networks a crashed run left behind
clean-devices: setup
	$(JARVIS) cleanup
