# Two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: venv demo test figures measured bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

demo: $(STAMP)
	mkdir -p out
	$(BIN)/dice-sweep sweep configs/demo.toml -o out/demo.h5 --png out/demo.png
	@echo "demo: final-state diagram written to out/demo.png (data in out/demo.h5)"

figures: $(STAMP)
	$(BIN)/python scripts/make_figures.py

measured: $(STAMP)
	$(BIN)/python scripts/measured_report.py

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

clean:
	rm -rf $(VENV) out .pytest_cache
