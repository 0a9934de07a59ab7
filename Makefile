# Two commands do all the set-up: `make demo` and `make test` (`make demo-all`: the slow extras too).
# Each creates .venv if needed and installs mimetic with its pinned dependencies.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo demo-all test lint bench clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -e '.[dev,track,usd,speech,batch,view]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/mimetic demo

demo-all: $(STAMP)
	$(BIN)/mimetic demo --all
	$(BIN)/python examples/real_heads.py mimetic-demo

test: $(STAMP)
	$(BIN)/python -m pytest

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples

bench: $(STAMP)
	for b in render engines basis rig export speech capture batch view live; do $(BIN)/python benchmarks/bench_$$b.py || exit 1; done

clean:
	rm -rf $(VENV) mimetic-demo
