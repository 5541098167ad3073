# `make run` reproduces every seed and the benchmark into out/ (then out/report.html); `make test`
# runs ruff and the tests. Both create .venv/ with the package installed in editable mode on first
# use: `run` installs the runtime dependencies and the arms from the field (example-robot-data), `test`
# adds the test extra (pytest, pytest-xdist, Pinocchio, ruff, mypy; the tests run on both cores, a file to a worker). `make lint` runs ruff and mypy on the public API
# ([tool.mypy] in pyproject.toml lists the modules).
PY := .venv/bin/python
STAMP := .venv/.installed
TEST_STAMP := .venv/.installed-test

$(STAMP): pyproject.toml
	python3 -m venv .venv
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[robots]'
	touch $(STAMP)

$(TEST_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(TEST_STAMP)

.PHONY: venv run test lint typecheck bench clean
venv: $(STAMP)

run: $(STAMP)
	MPLBACKEND=Agg $(PY) -m studies.run_all --out out

lint: $(TEST_STAMP) typecheck
	$(PY) -m ruff check qmt_drake tests studies models

typecheck: $(TEST_STAMP)
	$(PY) -m mypy

test: lint
	MPLBACKEND=Agg $(PY) -m pytest -q -n 2 --dist loadfile

bench: $(STAMP)
	MPLBACKEND=Agg .venv/bin/qmt-drake bench --out out

clean:
	rm -rf out .venv
