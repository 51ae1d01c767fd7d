# The two commands: `make demo` and `make test`. Each builds .venv on a fresh machine.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast lint bench validate clean griddyn-env envs

# Compiled at install (pip's default): where PYTHONDONTWRITEBYTECODE is set, as on CI, a
# module left uncompiled is compiled again by every process that imports it (tried with
# --no-compile: the install took 11 s instead of 31, and make test 183 s more).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[grid,cluster,andes,test]"
	touch $(STAMP)

# The two environments are built side by side (`envs`): the package's install runs on one
# core for about a minute, and GridDyn's (about 8 s) fits beside it on the other.
envs:
	@$(MAKE) --no-print-directory -j2 $(STAMP) griddyn-env

demo: envs
	$(VENV)/bin/loadbayes reproduce all --quick --out results --force
	@echo "loadbayes is in $(VENV)/bin: put it on PATH with '. $(VENV)/bin/activate' (or run $(CURDIR)/$(VENV)/bin/loadbayes)"

# The browser test of the HTML report needs Debian's chromium: installed here when
# missing and possible (CI runs as root); otherwise that one test says why it skips.
# pytest runs with PYTHONDONTWRITEBYTECODE unset (CI sets it): the package is installed
# editable, so pip compiled none of its modules, and with the variable set every process
# compiled them again, and every worker rewrote the asserts of all 230 test modules
# (collection 13.5 s a worker, 8.0 s with the cache; 30 Nov 2026). The files go to the
# clone's __pycache__ folders, which git ignores.
test: envs
	command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } || echo "chromium missing: the browser test will skip"
	$(VENV)/bin/ruff check src tests benchmarks
	env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -n 2 --dist worksteal -q tests

test-fast: $(STAMP)
	env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -n 2 --dist worksteal -q tests -m "not statistical and not integration"

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/ruff format --check src tests benchmarks

# The peers (PyMC pins an older numba) get their own environment, so that installing
# them never changes what the tests run against.
BENCH_VENV := .venv-bench
$(BENCH_VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(BENCH_VENV)/bin/python -m pip install --quiet -e ".[grid,cluster,bench]"
	touch $@

# Its older numba keeps its compiled kernels apart: numba rewrites a cache another numba
# version wrote, and the tests' environment then compiled everything again.
bench: $(BENCH_VENV)/.installed
	NUMBA_CACHE_DIR=$(CURDIR)/.numba-cache-bench $(BENCH_VENV)/bin/python benchmarks/run_all.py

# GridDyn (the independent CMLD simulator of src/loadbayes/cases/griddyn) needs Python >= 3.13: an
# environment of its own. Without a python3.13 (on PATH or under pyenv) `make test` goes
# on and the GridDyn tests skip, saying why.
PYTHON313 ?= $(shell for p in python3.13 $${PYENV_ROOT:-$$HOME/.pyenv}/versions/3.13*/bin/python3.13; do \
	"$$p" -c 'import sys; assert sys.version_info >= (3, 13)' >/dev/null 2>&1 && { command -v "$$p"; break; }; done)
GRIDDYN_VENV := .venv-griddyn
$(GRIDDYN_VENV)/.installed:
	$(PYTHON313) -m venv $(GRIDDYN_VENV)
	$(GRIDDYN_VENV)/bin/python -m pip install --quiet griddyn==0.13.0 numpy
	touch $@

griddyn-env:
	@if [ -n "$(PYTHON313)" ]; then $(MAKE) --no-print-directory $(GRIDDYN_VENV)/.installed; \
	else echo "python3.13 missing: the GridDyn tests will skip"; fi

# GridDyn's environment too: test_composite_generators and test_predict fit its events.
validate: envs
	$(PY) -m loadbayes.studies.calibration.run --out results/validation
	$(PY) -m loadbayes.studies.calibration.composite_recovery --events 200 \
		--output results/validation/composite_recovery.json
	$(PY) -m loadbayes.studies.calibration.composite_independent --events 144 \
		--output results/validation/composite_independent.json
	$(PY) -m loadbayes.studies.calibration.fleet_coverage \
		--output results/validation/fleet_coverage.json
	env -u PYTHONDONTWRITEBYTECODE LOADBAYES_VALIDATE=1 $(PY) -m pytest -q -p no:cacheprovider -m statistical \
		tests/integration/test_cli_exit_clean.py tests/statistical/test_cvr_coverage.py \
		tests/integration/test_predict.py tests/statistical/test_archive_pool_coverage.py \
		tests/statistical/test_drift_fleet_coverage.py tests/statistical/test_drift_year.py \
		tests/statistical/test_archive_end_to_end.py tests/statistical/test_fleet_heterogeneous.py \
		tests/statistical/test_composite_fan.py tests/statistical/test_composite_generators.py \
		tests/statistical/test_predict_band_average.py tests/integration/test_readme.py \
		tests/integration/test_zip_study.py tests/statistical/test_reclose_model_error.py \
		tests/statistical/test_parts_negative_sequence.py tests/statistical/test_parts_stall_threshold.py \
		tests/statistical/test_sbc.py tests/integration/test_composite_waveform.py \
		tests/statistical/test_composite_recovery.py tests/statistical/test_composite_independent.py \
		tests/statistical/test_composite_ramps.py tests/statistical/test_parts_ar1_coverage.py

clean:
	rm -rf $(VENV) $(BENCH_VENV) $(GRIDDYN_VENV) results .pytest_cache .ruff_cache
