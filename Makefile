# hair_sim: every target bootstraps what it needs into .venv (Python 3.11).
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
BOOT_PYTHON ?= $(shell command -v python3.11 || command -v python3)
MSG_SRCS := $(shell find msg_defs -type f -not -name '*~')

PIP_VERSION := 26.3
STAMP_DEPS := $(VENV)/.stamp-deps
STAMP_MSGS := $(VENV)/.stamp-msgs
STAMP_PKG := $(VENV)/.stamp-pkg
STAMP_WARM := $(VENV)/.stamp-warm
PY_SRCS := $(shell find hair_sim -name '*.py')

.PHONY: setup test demo lint clean clean-cache

setup: $(STAMP_DEPS) $(STAMP_MSGS) $(STAMP_PKG) $(STAMP_WARM)

# Python 3.11: the pinned ROS 2 Jazzy wheels and build tools (python3.12 got as far as
# building the messages, where the pinned setuptools fails: pkgutil.ImpImporter is gone)
$(PY):
	@test -n "$(BOOT_PYTHON)" && "$(BOOT_PYTHON)" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
	  2>/dev/null || { echo "make: hair_sim needs Python 3.11; BOOT_PYTHON ($(or $(BOOT_PYTHON),no python3.11" \
	  "or python3 on PATH)) is $$("$(BOOT_PYTHON)" --version 2>/dev/null || echo not a Python)." \
	  "Set BOOT_PYTHON=/path/to/python3.11" >&2; exit 1; }
	"$(BOOT_PYTHON)" -m venv $(VENV)

# Pinned dependencies; reinstalled only when the requirement files change. pip first: the
# pip that comes with Python 3.11 falls back to `setup.py develop` for this package, which
# follows setup.cfg's ament script_dir and leaves .venv/bin without the console scripts.
$(STAMP_DEPS): requirements.txt constraints.txt | $(PY)
	$(PY) -m pip install --disable-pip-version-check -q "pip==$(PIP_VERSION)"
	$(PY) -m pip install --disable-pip-version-check -q -r requirements.txt -c constraints.txt
	touch $@

# hair_sim_msgs, built with plain CMake into the venv prefix; rebuilt only when msg_defs/ changes.
# The build folder is the venv's own: CMake's cache remembers where it found ament, and a
# shared build/msg_defs built a second venv (make setup VENV=...) against the first's.
$(STAMP_MSGS): $(STAMP_DEPS) $(MSG_SRCS) tools/build_msgs.sh
	tools/build_msgs.sh $(VENV) $(VENV)/build/msg_defs
	touch $@

# hair_sim itself, editable; console scripts also go where `ros2 run` looks (<prefix>/lib/hair_sim).
$(STAMP_PKG): $(STAMP_DEPS) setup.py setup.cfg package.xml resource/hair_sim tools/install_ros_prefix.py
	$(PY) -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation -e .
	$(PY) tools/install_ros_prefix.py $(VENV)
	touch $@

# numba's on-disk cache of the node's kernels (both strand models), compiled afresh whenever
# a source changes, so that a first run does not stall for seconds compiling (the first
# `make demo` on a fresh clone ran at 30 Hz from 16.9 s, from 0.8 s after this) and no
# kernel keeps machine code of a kernel it calls that was edited in another file
# (see clean-cache)
$(STAMP_WARM): $(STAMP_PKG) $(STAMP_MSGS) $(PY_SRCS)
	find hair_sim \( -name '*.nbi' -o -name '*.nbc' \) -delete
	$(PY) -m hair_sim.warmup
	touch $@

# Three passes: the tests that start no node share the two cores (a file to a worker, so a
# module's fixture runs once); then those of test/conftest.py's SERIAL_FOLDERS, which start
# nodes and servers, two files at once (a ROS domain to a worker); then its QUIET ones,
# which time rates, latencies or frames against a floor, one at a time on a machine of
# their own. Every pass runs even when one before it failed, so one run reports every
# failure; the target fails if any did. Each prints its ten slowest tests (a slow CI run
# shows where its time went). `pytest test` still runs everything in one process.
test: setup
	$(PY) -m pytest -n 2 --dist loadscope --no-loadscope-reorder -m "not serial" \
		--durations=10 test; shared=$$?; \
	$(PY) -m pytest -n 2 --dist loadscope --no-loadscope-reorder -m "serial and not quiet" \
		--durations=10 test; paired=$$?; \
	$(PY) -m pytest -m quiet --durations=10 test; alone=$$?; \
	exit $$(( shared != 0 ? shared : paired != 0 ? paired : alone ))

# The node with the sample style, a scripted head and wind, in meshcat: prints the URL.
demo: setup
	$(VENV)/bin/hair_sim_demo $(DEMO_ARGS)

lint: setup
	$(PY) -m pytest test/test_flake8.py test/test_pep257.py

# numba's cache=True keys each kernel on its own file: a kernel in one file that calls one
# edited in another keeps its stale machine code until the caches go (`make setup` wipes and
# rebuilds them when a source changes; this is for edits made outside make's view)
clean-cache:
	find hair_sim \( -name '*.nbi' -o -name '*.nbc' \) -delete
	rm -f $(STAMP_WARM)

clean: clean-cache
	rm -rf build $(VENV)
