# The two commands of the README: `make demo` (main job) and `make test` (test suite).
# Each creates the virtual environment on first use.

PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_SCENARIOS ?= ur10e_waypoints mz04d_waypoints rover_arm_waypoints path_following path_following_continuous panel_operation ur10e_joint_tour

.PHONY: demo test lint bench picture docs clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,docs]'
	touch $(STAMP)

demo: $(STAMP)
	@set -e; for s in $(DEMO_SCENARIOS); do \
		$(BIN)/guidedarm run $$s --out runs/$$s; \
	done; \
	$(BIN)/guidedarm demo-index runs; \
	echo "make demo: wrote summary.json, plots and replay.html for each scenario under runs/, and runs/index.html"

# --no-loadscope-reorder keeps the order of tests/conftest.py (slow modules first).
# --max-worker-restart=0: after replacing a crashed worker, pytest-xdist 3.8's loadfile
# scheduler can wait forever (pytest-xdist#1313); a crash ends the session instead.
test: $(STAMP)
	sh tests/setup_browser.sh
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/pytest -n 2 --dist loadfile --no-loadscope-reorder --max-worker-restart=0

lint: $(STAMP)
	$(BIN)/ruff check . && $(BIN)/ruff format --check .

bench: $(STAMP)
	@for b in tests/benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b; done

# The documentation site into site/ (strict: any warning fails), the tutorials executed
# so that their pages show their outputs.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 GUIDEDARM_DOCS_EXECUTE=true $(BIN)/mkdocs build --strict
	@echo "make docs: wrote the site to site/ (open site/index.html)"

picture: $(STAMP)
	$(BIN)/guidedarm picture docs/guidedarm.png

clean:
		rm -rf $(VENV) runs site .pytest_cache
