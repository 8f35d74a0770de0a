# Two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: venv demo test test-explore test-measured test-fuzz figures measured bench shards clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

# on both cores (pytest-xdist): one process for the whole suite took 14 min on the 2-core machine
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist worksteal

# the property tests with fresh random examples (`make test` draws the same ones every run)
test-explore: $(STAMP)
	HYPOTHESIS_PROFILE=explore $(BIN)/python -m pytest -q tests/test_config.py tests/physics/test_impact.py tests/physics/test_flight.py

# the long cases of the measured-data loop on independent synthetic drops (minutes)
test-measured: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests/measured

# 10^5 fuzzed starts for stalls, and 10^5 random dice between walls with every kernel effect
# that must end decided, propped on a wall, or (event budget) still moving (issue 33), shared
# among the seeds of DICE_SWEEP_FUZZ_SEEDS (default 2,3): DICE_SWEEP_FUZZ_SEEDS=4 make test-fuzz
test-fuzz: $(STAMP)
	$(BIN)/python -m pytest -q -m slow tests/physics/test_stalls.py

demo: $(STAMP)
	mkdir -p out
	$(BIN)/dice-sweep sweep configs/demo.toml -o out/demo.h5 --png out/demo.png --resume
	@echo "demo: final-state diagram written to out/demo.png (data in out/demo.h5)"

figures: $(STAMP)
	$(BIN)/python scripts/make_figures.py

measured: $(STAMP)
	$(BIN)/python scripts/measured_report.py

# docs/forecast.md and docs/figures/forecast_*.png from the real drops (issue 18); minutes on 2 cores
.PHONY: forecast
forecast: $(STAMP)
	$(BIN)/python scripts/forecast_report.py

bench: $(STAMP)
	$(BIN)/python scripts/bench_kernel.py

# The measured tables of docs/chaos.md (issue 6), one script call per table; minutes on 2 cores.
.PHONY: chaos
chaos: $(STAMP)
	$(BIN)/python scripts/chaos_tables.py validation
	$(BIN)/python scripts/chaos_tables.py sides
	$(BIN)/python scripts/chaos_tables.py walls
	$(BIN)/python scripts/chaos_tables.py time_step
	$(BIN)/python scripts/chaos_tables.py contact
	$(BIN)/python scripts/chaos_tables.py refine
	$(BIN)/python scripts/chaos_tables.py control
	$(BIN)/python scripts/chaos_tables.py scatter --num 256

# A sweep cut into shards, one process each, then merged (docs/scaling.md):
#   make -j2 shards CONFIG=configs/fig10.toml SHARDS=8 SET="--set grid.x.num=1024"
# gives out/shards/fig10/part-I-of-8.h5 and out/fig10.h5. A shard is written to .partial and
# renamed only when complete, so an interrupted run is resumed by the same command, and make
# never takes an incomplete file for a finished one. SET is part of what a part is: the file
# SET_STAMP holds it and is rewritten only when it changes, so the parts depend on it; a change
# removes the parts, .partial files and merged file of the previous SET (--resume cannot finish
# those, and the old merged file would look like the new one).
CONFIG ?= configs/fig08.toml
SHARDS ?= 4
SET ?=
SHARD_OUT ?= out
SWEEP_NAME := $(basename $(notdir $(CONFIG)))
SHARD_DIR := $(SHARD_OUT)/shards/$(SWEEP_NAME)
SHARD_PARTS := $(foreach i,$(shell seq 0 $$(($(SHARDS) - 1))),$(SHARD_DIR)/part-$(i)-of-$(SHARDS).h5)
SET_STAMP := $(SHARD_DIR)/set-of-$(SHARDS).txt
SET_QUOTED := '$(subst ','\'',$(SET))'

shards: $(SHARD_OUT)/$(SWEEP_NAME).h5

.PHONY: FORCE
$(SET_STAMP): FORCE
	@mkdir -p $(SHARD_DIR)
	@if [ ! -f $@ ] || [ "$$(cat $@)" != $(SET_QUOTED) ]; then \
		echo "shards: SET is now $(SET_QUOTED); removing the parts and merged file of any other SET"; \
		rm -f $(SHARD_DIR)/part-*-of-$(SHARDS).h5 $(SHARD_DIR)/part-*-of-$(SHARDS).h5.partial $(SHARD_OUT)/$(SWEEP_NAME).h5; \
		printf '%s\n' $(SET_QUOTED) > $@; \
	fi

$(SHARD_DIR)/part-%-of-$(SHARDS).h5: $(CONFIG) $(SET_STAMP) | $(STAMP)
	@mkdir -p $(SHARD_DIR)
	$(BIN)/dice-sweep sweep $(CONFIG) $(SET) -o $@.partial --shard $*/$(SHARDS) --workers 1 --resume --quiet
	mv $@.partial $@

$(SHARD_OUT)/$(SWEEP_NAME).h5: $(SHARD_PARTS)
	rm -f $@.partial
	$(BIN)/dice-sweep merge $^ -o $@.partial
	mv $@.partial $@

clean:
	rm -rf $(VENV) out .pytest_cache
