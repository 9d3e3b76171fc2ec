# The two commands a fresh machine needs (see README.md):
#   make demo   set up .venv, install dermis, render the built-in scene to out/demo.png
#   make test   the same set-up, then the whole test suite (on TEST_WORKERS=2 processes, pytest-xdist)
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
GL_PACKAGES := libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri
# the viewer's window tests run under a virtual X server
TEST_PACKAGES := xvfb xauth libxrandr2 libxcursor1 libxi6 libxinerama1

.PHONY: demo test sysdeps test-sysdeps install cycles bench bench-batch fuzz mc-tables subsurface-transfer clean

sysdeps:
	@scripts/ensure-system-packages.sh $(GL_PACKAGES)

test-sysdeps:
	@scripts/ensure-system-packages.sh $(GL_PACKAGES) $(TEST_PACKAGES)

$(VENV)/bin/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "dermis needs Python 3.11+"'
	$(PYTHON) -m venv $(VENV)

$(VENV)/.installed: $(VENV)/bin/python pyproject.toml
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	@touch $@

install: $(VENV)/.installed

# Blender as a Python module (the `cycles` extra: bpy, a ~370 MB download, 800 MB installed), resolved
# together with the test extra in one pip run. bpy pins numpy>=1.26,<2, so this environment gets numpy
# 1.26.4 (dermis runs on 1.26 and 2.x). bpy is built for CPython 3.11 only: on another Python this
# falls back to the test extra and the Cycles tests skip (the Cycles commands say how to install it).
$(VENV)/.cycles: $(VENV)/bin/python pyproject.toml
	$(PY) -m pip install --quiet --upgrade pip
	@$(PY) -m pip install --quiet -e ".[test,cycles]" \
		|| { echo "note: the cycles extra (bpy) did not install for this Python; the Cycles tests will skip"; \
		     $(PY) -m pip install --quiet -e ".[test]"; }
	@touch $(VENV)/.installed $@

cycles: $(VENV)/.cycles

demo: sysdeps install
	@mkdir -p out
	$(VENV)/bin/dermis render --out out/demo.png --size 768x768
	@echo "demo image: $(CURDIR)/out/demo.png"

# the suite on TEST_WORKERS processes (pytest-xdist), each taking one whole test file at a time in the
# order tests/conftest.py gives (the slowest files first); TEST_WORKERS=0 runs it in this process
TEST_WORKERS ?= 2
test: test-sysdeps cycles
	$(PY) -m pytest -q -ra --durations=25 -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

bench: sysdeps install
	$(VENV)/bin/dermis bench

# batch throughput (1, 2 local workers, Ray with 2 actors): pip install -e ".[ray]" first
bench-batch: sysdeps install
	$(PY) benchmarks/batch_bench.py --renders 200

# the skin presets' Monte Carlo tables shipped in src/dermis/data (photons and seeds recorded in the
# file; about 1-3 minutes a preset on 2 cores): after changing a preset or the skin coefficients
mc-tables: install
	nice -n 10 $(PY) -m dermis.profiles.monte_carlo_tables $(PRESETS)

# tsd's baked subsurface transfer of the example head's thin parts (generated data, not in git: about
# 10 min wall on an idle 2-core machine, 28-33 min beside other work; seeded (bit-identical reruns), written to dermis's cache folder,
# found there by the mesh's content).
# Without it tsd renders the head without the transfer (benchmarks/RESULTS.md, round 10: the back-lit
# ear's red 0.77 instead of 0.88 of Cycles'). A bake of an older format or recipe (round 11's, before
# round 12's control variate) is ignored with a warning: run this again. About 2.9 MB.
# TRANSFER_SCENE to bake another scene's mesh and medium.
TRANSFER_SCENE ?= examples/lee-perry-smith.toml
subsurface-transfer: sysdeps install
	nice -n 10 $(PY) -m dermis.subsurface_transfer $(TRANSFER_SCENE)

# >= 10,000 generated bad (and good) inputs; counts go to benchmarks/RESULTS.md "Reliability"
# (FUZZ_CASES, FUZZ_SEED to change the count or replay a seed)
FUZZ_CASES ?= 10000
fuzz: sysdeps install
	$(PY) scripts/fuzz.py --cases $(FUZZ_CASES) $(if $(FUZZ_SEED),--seed $(FUZZ_SEED))

clean:
	rm -rf out .pytest_cache build *.egg-info src/*.egg-info
