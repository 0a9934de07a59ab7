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
# also after a failure, which still fails the target. Slow ones on 2 cores (full runs): physics ~3 min
# (--quick 4 min under load), quality over 10 min with its four engines (--quick alone took 9 min),
# sweep_motion ~9 min, memory ~23 min, validate_capture 19-25 min (its videos cached or not).
bench: $(STAMP)
	rm -f benchmarks/out/*.md
	status=0; for b in bench_render bench_engines bench_basis bench_rig bench_export bench_speech \
		bench_capture bench_batch bench_view bench_live bench_memory bench_physics bench_proxy bench_quality \
		sweep_motion validate_capture; do \
		$(BIN)/python benchmarks/$$b.py || { status=1; echo "$$b.py failed"; }; done; \
	$(BIN)/python benchmarks/write_docs.py && exit $$status

clean:
	rm -rf $(VENV) mimetic-demo
