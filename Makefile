# starsense — two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= report

.PHONY: demo test test-fast lint bench bench-peers bench-zoo clean

$(STAMP): pyproject.toml setup.py src/starsense/detect/_clipc.c
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,scale,gaia]'
	touch $(STAMP)

demo: $(STAMP)  ## the main job: the performance report for the default sensor
	$(BIN)/starsense report --out $(OUT)
	@echo "Open $(OUT)/index.html"

test: $(STAMP)  ## lint, format, the stage contract, then the whole suite (what CI runs)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench
	$(BIN)/lint-imports

bench: $(STAMP)  ## time the hot paths; results to bench/results/*.json (+ peers if installed)
	$(BIN)/python bench/run.py
	$(BIN)/python bench/datasheet_check.py  # measured/predicted over 1,000 frames per sensor
	@if [ -x bench/peers/.venv/bin/python ]; then \
		$(BIN)/python bench/peers/compare.py --cedar-python bench/peers/.venv/bin/python; \
	else echo "(peer comparison: run 'make bench-peers' once to install cedar-solve)"; fi

# Peer comparison (development only): cedar-solve 0.5.1 needs NumPy < 2 (np.math) and Pillow < 9,
# so it gets its own venv, bench/peers/.venv (git-ignored by .venv/). If that cannot be installed,
# bench-peers still prints starsense's side and says why cedar-solve is unavailable.
PEERS       := bench/peers/.venv
PEERS_STAMP := $(PEERS)/.installed

$(PEERS_STAMP):
	$(PYTHON) -m venv $(PEERS)
	$(PEERS)/bin/python -m pip install --quiet --upgrade pip
	$(PEERS)/bin/python -m pip install --quiet "cedar-solve==0.5.1" "numpy<2"
	touch $@

bench-zoo: $(STAMP)  ## the sensor zoo (40 seeded designs + the 768x512 CCD), at rest and 1 deg/s; bench/results/zoo.json
	$(BIN)/python bench/zoo.py --designs 40 --frames 100

bench-peers: $(STAMP)  ## starsense vs cedar-solve on the same inputs; bench/results/peer_cedar.json
	-@$(MAKE) --no-print-directory $(PEERS_STAMP) || echo "(cedar-solve install failed; see above)"
	$(BIN)/python bench/peers/compare.py --cedar-python $(PEERS)/bin/python

clean:
	rm -rf $(VENV) bench/peers/.venv build *.egg-info src/*.egg-info .pytest_cache report
