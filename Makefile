# The two commands of the README: `make demo` (main job) and `make test` (test suite).
# Each creates the virtual environment on first use.

PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_SCENARIOS ?= ur10e_waypoints mz04d_waypoints rover_arm_waypoints path_following path_following_continuous panel_operation ur10e_joint_tour

.PHONY: demo test test-stress lint bench picture docs clean

$(STAMP): pyproject.toml setup.py $(wildcard csrc/*.[ch])
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

# The timing-sensitive test files N times (slow tests included) while a CPU hog keeps one
# core busy; a round is clean when it passes with nothing skipped. Not part of `make test`
# (a round takes about 3 minutes on 2 cores).
N ?= 10
STRESS_FILES ?= tests/test_hardware_*.py tests/test_live_view.py tests/test_interrupts.py
test-stress: $(STAMP)
	@$(BIN)/python -c 'while True: pass' & hog=$$!; \
	trap 'kill $$hog 2>/dev/null' EXIT INT TERM; \
	mkdir -p runs/stress; clean=0; \
	for round in $$(seq 1 $(N)); do \
		log=runs/stress/round_$$round.log; \
		$(BIN)/pytest -n 2 --dist loadfile --no-loadscope-reorder --max-worker-restart=0 \
			-p no:cacheprovider $(STRESS_FILES) > $$log 2>&1; code=$$?; \
		summary=$$(tail -n 1 $$log); \
		if [ $$code -eq 0 ] && ! echo "$$summary" | grep -q skipped; then \
			clean=$$((clean + 1)); echo "round $$round/$(N): clean: $$summary"; \
		else echo "round $$round/$(N): NOT clean ($$log): $$summary"; fi; \
	done; \
	echo "$$clean/$(N) rounds clean"; test $$clean -eq $(N)

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
