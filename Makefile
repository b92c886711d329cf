# hilrig developer commands. Every target creates .venv and installs what it needs.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= build
# pytest workers for make test (pytest-xdist); TEST_WORKERS=0 runs the suite in one process
TEST_WORKERS ?= 2
# The browser tests drive Debian's chromium (tests/study); installed once, as root or with sudo.
CHROMIUM := /usr/bin/chromium
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test lint typecheck docs bench lock clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev,ray]'
	touch $(STAMP)

demo: $(STAMP)  ## the main job: the paper table, then its collisions recorded on the emulated rig
	$(BIN)/hilrig demo --out $(OUT)/demo

test: lint typecheck docs $(CHROMIUM)  ## lint, type-check, build the docs site and run every test
	$(BIN)/python -m pytest -n $(TEST_WORKERS)

# One install at a time: two `make test` started together on a fresh machine would otherwise race
# for dpkg's lock (flock serialises them, the second finds chromium there); apt also waits for
# any other apt (DPkg::Lock::Timeout).
$(CHROMIUM):
	$(SUDO) flock /var/lock/hilrig-chromium.lock sh -c 'test -x $(CHROMIUM) || { \
	  apt-get -o DPkg::Lock::Timeout=600 update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq chromium; }'

lint: $(STAMP)
	$(BIN)/ruff check hilrig tests benchmarks
	$(BIN)/ruff format --check hilrig tests benchmarks

typecheck: $(STAMP)
	$(BIN)/mypy

docs: $(STAMP)  ## the docs site in $(OUT)/site (mkdocs.yml; strict: a broken link or reference fails)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir $(OUT)/site

bench: $(STAMP)  ## benchmarks; results in benchmarks/results/latest.json
	$(BIN)/python -m benchmarks

lock: $(STAMP)  ## re-pin constraints.txt from the current environment
	{ echo "# Pinned versions used by make (pip install -c constraints.txt). Regenerate with: make lock"; \
	  $(BIN)/python -m pip freeze --exclude-editable; } > constraints.txt

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .mypy_cache .ruff_cache
