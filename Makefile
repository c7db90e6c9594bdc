# Set-up and the two jobs of the README. Needs only python3 (>= 3.11) and make.
SHELL  := /bin/bash
.SHELLFLAGS := -eo pipefail -c
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup demo test bench samples outputs lint clean

$(STAMP): pyproject.toml requirements.lock
	@echo "impactcli: setting up $(VENV) with the pinned versions of requirements.lock (first time: under 3 minutes on 2 vCPUs)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --disable-pip-version-check --progress-bar off -c requirements.lock -e '.[dev,urdf,dask,robots]' \
	    | grep --line-buffered -E '^(Collecting|Successfully installed)' | cut -c1-100
	touch $(STAMP)

setup: $(STAMP)

# The main job on a bundled sample log: detect with thresholds calibrated on the
# collision-free sample logs, write the timeline, signals and a Rerun recording.
demo: $(STAMP)
	@echo "impactcli: detecting contacts in sample_logs/csv/assist_impacts.csv.gz (15 simulated impacts) with the config calibrated on the collision-free sample logs"
	$(BIN)/impactcli detect sample_logs/csv/assist_impacts.csv.gz \
	    --config sample_logs/assist_like.config.toml --signals --rerun -o out/demo
	@echo
	@echo "Wrote out/demo/assist_impacts.timeline.json (incidents and events), .signals.parquet and .rrd."
	@echo "Next:"
	@echo "  $(BIN)/impactcli report sample_logs/csv/assist_impacts.csv.gz --config sample_logs/assist_like.config.toml -o out/report.html   # the safety-audit report"
	@echo "  $(BIN)/impactcli evaluate out/demo/assist_impacts.timeline.json   # against the log's labels"
	@echo "  $(BIN)/impactcli view out/demo/assist_impacts.rrd   # residuals against thresholds in the Rerun viewer (needs a display: elsewhere, rerun FILE.rrd)"

# Timeline, Rerun recording and one audit report (HTML + JSON) for every sample log, CSV
# and MCAP copies in separate folders (their stems collide), each arm with its own config.
outputs: $(STAMP)
	for fmt in csv mcap; do \
	  for arm in assist:assist_like heavy:heavy_geared; do \
	    pre=$${arm%%:*}; cfg=sample_logs/$${arm#*:}.config.toml; \
	    $(BIN)/impactcli detect sample_logs/$$fmt/$${pre}_*.$${fmt/csv/csv.gz} --config $$cfg \
	        --signals --rerun --jobs 2 -o out/$$fmt || exit $$?; \
	  done; \
	  $(BIN)/impactcli report out/$$fmt/*.timeline.json -o out/$$fmt/report.html \
	      --json out/$$fmt/report.json || exit $$?; \
	done

# The linters (ruff, mypy: 0 errors is the bar) and the tests — the README's test command.
# TEST_WORKERS pytest processes (pytest-xdist) share the tests, each taking the next when
# it is free; TEST_WORKERS=0 runs them in this process. mypy (one core, about 35 s on a
# cold cache) runs beside the tests; its report follows theirs; either failing fails make;
# Ctrl-C or a TERM stops it too (exit 130, 143).
TEST_WORKERS ?= 2
test: $(STAMP)
	$(BIN)/ruff check impactcli tests
	@echo "$(BIN)/mypy impactcli  (beside the tests; its report follows theirs)"
	@$(BIN)/mypy impactcli > $(VENV)/mypy.out 2>&1 & mypy=$$!; tests=0; \
	trap 'kill $$mypy 2>/dev/null; exit 130' INT; trap 'kill $$mypy 2>/dev/null; exit 143' TERM; \
	echo "$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal"; \
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist worksteal || tests=$$?; \
	lint=0; wait $$mypy || lint=$$?; \
	echo "mypy impactcli:"; cat $(VENV)/mypy.out; \
	if [ $$lint != 0 ]; then echo "make test: mypy found errors (above)"; exit $$lint; fi; \
	exit $$tests

# Every benchmark of the README's performance section (about 10 minutes on 2 cores).
bench: $(STAMP)
	$(BIN)/python tests/benchmarks/bench_mcap_decode.py
	$(BIN)/python tests/benchmarks/bench_rls.py
	$(BIN)/python tests/benchmarks/bench_rerun.py
	$(BIN)/python tests/benchmarks/bench_sim.py
	$(BIN)/python tests/benchmarks/bench_detect_e2e.py 120
	$(BIN)/python tests/benchmarks/sample_quality.py

samples: $(STAMP)
	$(BIN)/python -m impactcli.sim.sample_logs sample_logs

lint: $(STAMP)
	$(BIN)/ruff check impactcli tests
	$(BIN)/mypy impactcli

clean:
	rm -rf $(VENV) out .pytest_cache
