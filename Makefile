# Two entry points, each bootstrapping its own virtualenv:  make demo  /  make test
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint bench clean upgrade

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev]'
	touch $(STAMP)

# The newest versions pyproject.toml allows, written back to constraints.txt (then: make test).
upgrade:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet --upgrade -e '.[dev]'
	head -3 constraints.txt > constraints.new
	$(BIN)/python -m pip freeze --exclude-editable | grep -v '^vestim' >> constraints.new
	mv constraints.new constraints.txt
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/vestim demo --out out/demo

test: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -q -m "not slow" tests

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_sim.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache
