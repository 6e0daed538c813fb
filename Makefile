# One command each for a newcomer: `make demo` and `make test` create .venv when missing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast fuzz lint docs bench results clean

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/paintcell run scenarios/door.toml --out results/door
	@echo "Results: results/door (report.html, metrics.json, plan.json, trajectory.npz/.csv, trace.npz)"

# pytest-xdist workers for the suite (`make test TEST_WORKERS=4`), each test sent to the next free
# worker (--dist load; module fixtures are built once per worker that runs their file). A worker
# that crashes fails the test it was running, so the run fails.
TEST_WORKERS ?= 2

test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist load
	$(BIN)/paintcell check scenarios/ --fast --jobs 2 --junit results/check-junit.xml --out results/check

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist load -m "not slow and not fuzz_full"

# The whole fuzz suite, its long cases (marker fuzz_full) included; `make test` runs its fast slice.
fuzz: $(STAMP)
	$(BIN)/python -m pytest -q -m "" tests/fuzz

lint: $(STAMP)
	$(BIN)/ruff check paintcell tests benchmarks
	$(BIN)/mypy

# The documentation site (mkdocs.yml) into site/; --strict: a broken link, a public API object
# without a docstring or a scenario key without a description fails the build.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# results.py writes docs/results.md (every scenario and the paper tables): `make results`;
# after `make test`, `benchmarks/results.py --from results/check` reads the check's runs instead;
# `--generality F.md ...` adds the tables of `benchmarks/generality.py --markdown F.md` (~25 min).
bench: $(STAMP)
	for b in benchmarks/*.py; do [ $$b = benchmarks/results.py ] && continue; \
		echo "== $$b"; $(BIN)/python $$b || exit 1; done

results: $(STAMP)
	$(BIN)/python benchmarks/results.py --jobs 2

clean:
	rm -rf $(VENV) results build site *.egg-info
