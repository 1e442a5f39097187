# Two commands set up a fresh machine (Python 3.11 and the package registries only):
#   make run    create .venv, install the pinned lock and the package, run `dvc repro`
#   make test   the test suite (end-to-end tests included; `make test-fast` skips them)
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install run test test-fast bench bench-scale trials trials-quick demo-check day-two-check ui-check lint simulate clean

install: $(STAMP)

# uv installs the lock (pinned below; it fetches and unpacks the wheels in parallel, a fifth of
# pip's time here); where it cannot (an index only pip is configured for), pip does. The
# packages' bytecode is compiled by compileall on every core (pip compiles one file at a time),
# their own test suites left out (a fifth of the files, never imported) and so are sympy and
# cfn-lint (moto's CloudFormation checks, the only importer of sympy), the repository's own
# code too (an editable install is not compiled): every stage is a new process, and where
# PYTHONDONTWRITEBYTECODE is set each would compile the package again.
OWN_CODE := pipeline schemas tests benchmarks
COMPILE_OWN := $(BIN)/python -m compileall -q -j 0 $(OWN_CODE)
PIP := $(BIN)/python -m pip install --quiet --disable-pip-version-check
UV := $(BIN)/uv pip install --python $(BIN)/python --system-certs --quiet
FALLBACK := echo "uv could not install (above); installing with pip" >&2 &&

$(STAMP): requirements.lock pyproject.toml
	$(PYTHON) -c 'import sys; assert sys.version_info[:2] == (3, 11), "Python 3.11 is required"'
	$(PYTHON) -m venv $(VENV)
	$(PIP) "pip==26.3" "uv==0.13.9"
	$(UV) -r requirements.lock || { $(FALLBACK) $(PIP) --no-compile -r requirements.lock; }
	$(BIN)/python -m compileall -q -j 0 -x 'site-packages/(.*/tests/|sympy/|cfnlint/)' $(VENV)/lib
	$(UV) --no-deps -e . || { $(FALLBACK) $(PIP) --no-deps -e .; }
	$(COMPILE_OWN)
	touch $(STAMP)

run: install
	$(BIN)/dvc repro
	$(BIN)/thermal summary

# Two workers (pytest-xdist), a whole module at a time so that its shared pipeline run is built
# once; the slow modules start first, in the order tests/conftest.py gives them (xdist would
# otherwise reorder the modules by their number of tests): the 2-core CI machine's time.
PYTEST := PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python -m pytest -n 2 --dist loadscope --no-loadscope-reorder

test: install
	$(COMPILE_OWN)
	$(PYTEST) --durations=15

test-fast: install
	$(COMPILE_OWN)
	$(PYTEST) -m "not slow"

bench: install
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python -m benchmarks.bench

# Each stage's time and peak memory for 1, 2, 4 machines x 6, 12, 24 campaigns of the workshop
# twin, locally and on a local Dask cluster, and the growth exponents (reports/bench_scale.json)
bench-scale: install
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python -m benchmarks.bench_scale --dask

# Every hidden-effect case over seeds 1-5 (8 campaigns each) on both machines (the twin and
# benchmarks/independent_machine.py), then the trial tests (the twin, seed 1, every case, the
# proposed tests run; `make test` runs the smoke case only); trials-quick: 4 campaigns, 2 folds.
trials: install
	$(BIN)/python -m benchmarks.discrepancy_trials --seeds 1 2 3 4 5 --out reports/discrepancy_trials
	$(PYTEST) -m trials

trials-quick: install
	$(BIN)/python -m benchmarks.discrepancy_trials --quick --seeds 1 2 3 4 5 --out reports/discrepancy_trials_quick

demo-check: install
	$(BIN)/python -m benchmarks.discrepancy_demo_check --out reports/discrepancy_demo_check

# Trained on day 1, how good on day 2: the ranking score against later campaigns (workshop twin).
day-two-check: install
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python -m benchmarks.day_two_check --out reports/day_two_check

# The MLflow UI in headless Chromium after `make run`: screenshots and checks in reports/ui/.
# Playwright (tests/ui/) drives Debian's chromium (apt-get install -y chromium, or CHROMIUM=path).
ui-check: install
	$(BIN)/python -m tests.ui.check

lint: install
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

simulate: install
	$(BIN)/thermal simulate --preset demo --out data/raw

clean:
	rm -rf data/ingested data/validated data/separated reports metrics mlflow.db mlartifacts mlruns
