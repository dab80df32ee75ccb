# `make demo` and `make test` set themselves up: they create .venv if it is missing and install
# the project (editable, with the dev extra) into it. Only Python >= 3.11 is needed.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
WARMED := $(VENV)/.warmed

.PHONY: demo test test-emulator cross-tools fuzz bench lint clean venv docs serve-docs browser-deps test-browser

venv: $(STAMP)

# The project's bytecode, written ahead: pip compiles what it installs, but an editable install
# leaves the source tree to the interpreter, which compiles each module it imports on every run
# when PYTHONDONTWRITEBYTECODE is set (as in many containers and CI images): 0.26 s of CPU at
# every command's start, measured. Only files changed since the last pass are compiled again.
# The package folders (pyproject.toml's package-dir; tests/test_architecture.py checks the list):
# pytest compiles the tests its own way, and walking .venv would cost what the pass saves.
PACKAGE_FOLDERS := stcvision sim_camera controllers calibration
BYTECODE = $(BIN)/python -m compileall -q $(PACKAGE_FOLDERS)

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	@$(BYTECODE)
	@touch $(STAMP)

# the demo compiles the kernels it uses on its first run (and says so); the suite's workers would
# each compile the same ones, so make test compiles them first, in parallel processes
$(WARMED): $(STAMP)
	$(BIN)/python -m stcvision.warm
	@touch $(WARMED)

demo: $(STAMP)
	@$(BYTECODE)
	$(BIN)/stcvision demo --out out --force  # out/ is make demo's own folder: replace the last run

# everything but the emulator's and the browser's tests: a machine with Python and cc runs it
# whole, none skipped (make test-emulator, make test-browser run those)
test: $(WARMED)
	@$(BYTECODE)
	$(BIN)/python -m pytest -q -n 2 --dist worksteal -m "not emulator and not browser"

# the STC controller's firmware for the ATmega328P (avr-gcc) run in QEMU's uno machine
# (tests/emulator; needs make cross-tools). A target of its own rather than skips inside make
# test: what make test runs never depends on what happens to be installed
test-emulator: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m emulator tests/emulator

# the cross compiler and the emulator, from Debian/Ubuntu packages (root or sudo)
CROSS_PACKAGES := gcc-avr avr-libc binutils-avr qemu-system-misc
cross-tools:
	@if command -v avr-gcc >/dev/null && command -v qemu-system-avr >/dev/null; then echo "cross tools present"; \
	else $$(command -v sudo || true) apt-get update -qq && \
	     $$(command -v sudo || true) env DEBIAN_FRONTEND=noninteractive \
	       apt-get install -y -qq --no-install-recommends $(CROSS_PACKAGES); fi

# the labelling helper's review sheet in headless Chromium (Debian packages; run as root)
BROWSER_PACKAGES := chromium chromium-driver
browser-deps:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then echo "browser present"; \
	else $$(command -v sudo || true) apt-get update -qq && \
	     $$(command -v sudo || true) env DEBIAN_FRONTEND=noninteractive \
	       apt-get install -y -qq --no-install-recommends $(BROWSER_PACKAGES); fi

test-browser: $(STAMP)
	$(BIN)/python -m pytest -q -m browser tests/browser

# the fuzz tests (tests/fuzz, marked fuzz) with many examples: >= 10,000 cases, counted at the end
fuzz: $(STAMP)
	HYPOTHESIS_PROFILE=fuzz $(BIN)/python -m pytest -q -n 2 -m fuzz tests/fuzz

bench: $(STAMP)
	$(BIN)/stcvision bench

# the documentation site, built into site/ (git-ignored); --strict: any warning is an error
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

# the same site served with live reload on http://127.0.0.1:8000
serve-docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf out build site *.egg-info .pytest_cache
