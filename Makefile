# Two commands for a newcomer: `make run` and `make test`.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run fresh report test test-cluster smoke bench lint dryrun lock clean-venv

# (Re)build the environment when it is missing or older than the lock or the package metadata.
$(STAMP): environment.lock pyproject.toml
	@command -v $(PYTHON) >/dev/null || { echo "need $(PYTHON) on PATH (set PYTHON=...)"; exit 1; }
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -r environment.lock
	$(BIN)/pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/snakemake --cores 2

# Once after cloning or pulling: the committed tables, figures and models count as current (git
# writes src/ after results/, so they look older than their code), and Snakemake reruns only what
# an edit or a missing output needs, e.g. one figure in seconds (src/feeder/fresh.py).
fresh: $(STAMP)
	$(BIN)/python -m feeder.fresh

# The one-page HTML report of the default run (after `make run`; tests/test_report_browser.py).
report: $(STAMP)
	$(BIN)/snakemake --cores 2 --report results/report.html

test: $(STAMP)
	$(BIN)/python -m pytest -q

# The smoke simulations through SLURM on a one-node cluster on this machine (root: installs Debian's
# slurm-wlm and munge when missing), compared with a local run. `make test` runs it too when the
# cluster can be brought up, and skips it otherwise.
test-cluster: $(STAMP)
	profiles/slurm-local/up.sh
	FEEDER_REQUIRE_CLUSTER=1 FEEDER_CLUSTER_LOG=$(CURDIR)/results/cluster/slurm_smoke.log \
		$(BIN)/python -m pytest -q tests/test_cluster.py

# The benchmarks of the simulator (accuracy against time, yaw designs, jams, projected cost): hours.
bench: $(STAMP)
	$(BIN)/snakemake --cores 2 bench

smoke: $(STAMP)
	$(BIN)/snakemake --cores 2 --configfile config/smoke.yaml

# Also run by `make test` (tests/test_lint.py for the code style, tests/test_workflow.py for snakemake --lint).
lint: $(STAMP)
	$(BIN)/ruff check src tests
	$(BIN)/ruff format --check src tests
	$(BIN)/snakefmt --check Snakefile workflow
	$(BIN)/snakemake --lint
	$(BIN)/snakemake --lint --configfile config/smoke.yaml

# Regenerate environment.lock from the direct dependencies in pyproject.toml.
lock:
	rm -rf /tmp/feeder-lock && $(PYTHON) -m venv /tmp/feeder-lock
	/tmp/feeder-lock/bin/pip install --quiet --upgrade pip
	/tmp/feeder-lock/bin/pip install --quiet torch==2.13.0 .[test]
	/tmp/feeder-lock/bin/pip freeze --exclude feeder | sed 's/+cpu$$//' > environment.lock

clean-venv:
	rm -rf $(VENV)
