# `make demo` and `make test` do all set-up on a fresh machine.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test install bench clean can-tier

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# Buggy (the paper's Figures 3-5) as processes in real time for 30 s, recorded and drawn;
# `iotad demo` is the Figure 2 scheduler in text.
demo: $(STAMP)
	$(BIN)/python examples/buggy/demo.py --seconds 30

# Three workers (pytest-xdist), one test file each at a time so a file's fixtures are built once:
# most tests wait on real time (with two workers the suite kept 1.4 of this machine's 2 cores busy:
# 1,008 CPU s in 727 s), so three files at once fit 2 cores and cut the run by a fifth.
# `make test TEST_WORKERS=1` runs one file at a time.
TEST_WORKERS ?= 3

test: $(STAMP) can-tier
	$(BIN)/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --dist loadfile

# The CAN tests want a real SocketCAN bus: where the kernel lacks CAN, user-mode Linux gives one
# (docs/can.md). Installed when root with apt; skipped quietly otherwise (the tests pick another tier).
can-tier:
	@if { [ ! -x /usr/bin/linux.uml ] || ! command -v insmod >/dev/null 2>&1; } && [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing user-mode-linux and kmod for the CAN tests (docs/can.md)"; \
		(apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q user-mode-linux kmod) \
			>/dev/null 2>&1 || echo "could not install user-mode-linux: the CAN tests use another tier"; \
	fi

bench: $(STAMP)
	$(BIN)/python bench/kernel.py

clean:
	rm -rf $(VENV) build *.egg-info
