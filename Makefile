# jarvis-pytest: every target installs what it needs by itself.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
JARVIS := $(BIN)/jarvis
AGENT ?= oracle
WORKERS ?= 2
MARKERS ?=
PYTEST_ARGS ?=
STAMP := $(VENV)/.installed
# Python keeps byte-code caches (git-ignored __pycache__) for what make runs, even where the environment says not
# to: without them every pytest process (each xdist worker, each run a test starts) compiles and
# assertion-rewrites the harness again, about 0.7 CPU-s a process. pytest reads caches written earlier either way.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: setup engine images host-packages test test-android test-windows-real bench clean-devices

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

## host-packages: Debian packages the harness and tests use on the host (chromium for the dashboard's browser
## tests; adb for Android devices; mksh and toybox, Android's shell and tools, for the adb escaping tests;
## tesseract for GUI solutions that read text off the screen image; faketime for the test that sets the host's clock
## years ahead to show that devices do not drift with it)
host-packages:
	@missing=""; for c in chromium adb mksh toybox tesseract:tesseract-ocr faketime; do command -v $${c%%:*} >/dev/null || missing="$$missing $${c#*:}"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get -o DPkg::Lock::Timeout=600 update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -q $$missing >/dev/null; \
	  else echo "missing:$$missing: run  sudo apt-get install -y$$missing"; exit 1; fi; fi

## test: the project's own tests, container tests included
test: images host-packages
	$(BIN)/pytest -p no:cacheprovider tests -n $(WORKERS) $(PYTEST_ARGS)

## test-android: the Android library's quality gate on a live device (JARVIS_ANDROID_SERIAL=<serial>, or the
## emulator image prepared by `JARVIS_ANDROID_DOWNLOAD=1 jarvis images build --only android`); skipped with the
## reason where there is neither
test-android: setup host-packages
	$(BIN)/pytest -p no:cacheprovider tests/test_library_android.py -m android_live -rs $(PYTEST_ARGS)

## test-windows-real: the Windows QC sample (one template per application) on the kvm backend, a VM per task,
## then one report to paste: the golden's image, digest and Windows, and per task what passed, failed and why
## (prepare it first: JARVIS_WINDOWS_DOWNLOAD=1 jarvis images build --only windows-real; see
## fixtures/images/windows-real/README.md); skipped with the reason where there is no prepared KVM Windows
test-windows-real: setup
	JARVIS_WINDOWS_LIVE=1 $(BIN)/pytest -p no:cacheprovider -s -rs \
	  tests/test_device_windows_real.py::test_live_quality_gate $(PYTEST_ARGS)

## bench: run every task this machine's devices can run (AGENT=oracle by default; others are skipped with the
## reason) and write the tables and a report; MARKERS="ubuntu and atomic" narrows it. Tasks the agent fails are
## results (exit 0); an error, a timeout or any failure of the oracle exits 1
bench: images
	$(BIN)/pytest tasks -n $(WORKERS) --agent $(AGENT) $(if $(MARKERS),-m "$(MARKERS)") $(PYTEST_ARGS)

## clean-devices: remove containers and networks a crashed run left behind
clean-devices: setup
	$(JARVIS) cleanup
