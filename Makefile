# starsense — two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= report

.PHONY: demo test test-slow lint docs dist check-dist bench bench-peers bench-zoo bench-galsim bench-sweep clean

$(STAMP): pyproject.toml setup.py $(wildcard src/starsense/*/_*.c)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,scale,gaia,web]'
	touch $(STAMP)

demo: $(STAMP)  ## the main job: the performance report for the default sensor
	$(BIN)/starsense report --out $(OUT)
	@echo "Open $(OUT)/index.html"

test: $(STAMP)  ## lint, format, the stage contract, then the tests but the slow ones, in two processes
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q -m "not slow" -n 2

test-slow: $(STAMP)  ## the slow tests (long runs, real frames, timing under load), one process: CI runs them
	$(BIN)/python -m pytest -q -m slow

docs: $(STAMP)  ## the manual, warnings as errors: docs/_build/html/index.html
	rm -rf docs/_build docs/generated
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "Open docs/_build/html/index.html"

VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' pyproject.toml)
CHECK   := build/check-dist

dist: $(STAMP)  ## the release: the sdist and the wheel in dist/
	$(BIN)/python -m build --outdir dist .

# the wheel in a fresh venv with no compiler reachable (CC, CXX, LDSHARED fail), then a datasheet
check-dist: dist
	rm -rf $(CHECK)
	$(PYTHON) -m venv $(CHECK)
	CC=/bin/false CXX=/bin/false LDSHARED=/bin/false \
		$(CHECK)/bin/python -m pip install --quiet dist/starsense-$(VERSION)-*.whl
	cd $(CHECK) && bin/starsense datasheet --sensor st16 --trials 5

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench
	$(BIN)/lint-imports

bench: $(STAMP)  ## time the hot paths; results to bench/results/*.json (+ peers if installed)
	$(BIN)/python bench/run.py
	$(BIN)/python bench/datasheet_check.py  # measured/predicted over 1,000 frames per sensor
	$(BIN)/python bench/predict_bench.py --trade  # fast prediction of new designs; the 24-design trade
	@if [ -x bench/peers/.venv/bin/python ]; then \
		$(BIN)/python bench/peers/compare.py --cedar-python bench/peers/.venv/bin/python; \
	else echo "(peer comparison: run 'make bench-peers' once to install cedar-solve)"; fi

# Peer comparison (development only): cedar-solve 0.5.1 needs NumPy < 2 (np.math) and Pillow < 9,
# so it gets its own venv, bench/peers/.venv; tetra3rs (PyPI wheel) gets bench/peers/.venv-tetra3rs
# (both git-ignored). If one cannot be installed, bench-peers still runs and says why it is missing.
PEERS       := bench/peers/.venv
PEERS_STAMP := $(PEERS)/.installed
T3RS        := bench/peers/.venv-tetra3rs
T3RS_STAMP  := $(T3RS)/.installed

$(PEERS_STAMP):
	$(PYTHON) -m venv $(PEERS)
	$(PEERS)/bin/python -m pip install --quiet --upgrade pip
	$(PEERS)/bin/python -m pip install --quiet "cedar-solve==0.5.1" "numpy<2"
	touch $@

bench-zoo: $(STAMP)  ## held-out zoos (3 seeds drawn now, 16 designs each) first, then the tuning zoo (seed 23); bench/results/zoo*.json
	for k in 1 2 3; do $(BIN)/python bench/zoo.py --seed fresh --designs 16 --frames 100 --jobs 2 \
		--out bench/results/zoo_heldout_$$k.json || exit 1; done
	$(BIN)/python bench/zoo.py --designs 40 --frames 100 --jobs 2
	for f in bench/results/zoo_heldout_1.json bench/results/zoo_heldout_2.json \
		bench/results/zoo_heldout_3.json bench/results/zoo.json; do \
		$(BIN)/python bench/zoo_table.py $$f; done

bench-sweep: $(STAMP)  ## bad inputs and faults over every command: 1,000 cases of a seed drawn now (printed); the record's seed again to bench/results/bad_input_sweep.json
	$(BIN)/python bench/bad_input_sweep.py --cases 1000
	$(BIN)/python bench/bad_input_sweep.py --seed 159959856 --cases 1000 --out bench/results/bad_input_sweep.json

bench-galsim: $(STAMP)  ## the solver and the datasheet on GalSim frames (4 PSFs, rest and 1 deg/s; held-out zoo seed printed); bench/results/galsim_check.json
	$(BIN)/python bench/galsim_check.py --designs 6 --frames 40 --jobs 2

$(T3RS_STAMP):
	$(PYTHON) -m venv $(T3RS)
	$(T3RS)/bin/python -m pip install --quiet "tetra3rs==0.14.0"
	touch $@

bench-peers: $(STAMP)  ## starsense vs cedar-solve, tetra3rs, astrometry.net; bench/results/peers.json
	-@$(MAKE) --no-print-directory $(PEERS_STAMP) || echo "(cedar-solve install failed; see above)"
	-@$(MAKE) --no-print-directory $(T3RS_STAMP) || echo "(tetra3rs install failed; see above)"
	$(BIN)/python bench/peers/compare.py --cedar-python $(PEERS)/bin/python \
		--tetra3rs-python $(T3RS)/bin/python

clean:
	rm -rf $(VENV) bench/peers/.venv bench/peers/.venv-tetra3rs bench/peers/.cache build *.egg-info src/*.egg-info .pytest_cache report
