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

# Each benchmark prints its tables and writes them to benchmarks/out/NAME.md; write_docs.py then copies
# them between the <!-- bench:NAME --> markers of docs/benchmarks.md (sections not run keep theirs),
# also after a failure, which still fails the target.
bench: $(STAMP)
	rm -f benchmarks/out/*.md
	status=0; for b in render engines basis rig export speech capture batch view live memory; do \
		$(BIN)/python benchmarks/bench_$$b.py || { status=1; echo "bench_$$b.py failed"; }; done; \
	$(BIN)/python benchmarks/write_docs.py && exit $$status

clean:
	rm -rf $(VENV) mimetic-demo
