# `make run` reproduces the thesis chapters and the benchmark into out/; `make test` runs the tests.
# Both create .venv/ with the package installed in editable mode on first use.
PY := .venv/bin/python
STAMP := .venv/.installed

$(STAMP): pyproject.toml
	python3 -m venv .venv
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

.PHONY: venv run test bench clean
venv: $(STAMP)

run: $(STAMP)
	MPLBACKEND=Agg $(PY) -m studies.run_all --out out

test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -q

bench: $(STAMP)
	MPLBACKEND=Agg .venv/bin/qmt-drake bench --out out

clean:
	rm -rf out .venv
