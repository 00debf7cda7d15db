# The two commands of the README: `make demo` and `make test`.
# Both create .venv from pyproject.toml and build the FMUs on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
BIN = $(VENV)/bin
SCENE ?= spring_mass_nonlinear

.PHONY: demo test fmus benchmarks clean

$(VENV)/installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

fmus: $(VENV)/installed
	$(BIN)/dsim build-fmus

demo: fmus
	$(BIN)/dsim run build/ssp/$(SCENE).ssp --out results/$(SCENE).csv --plot results/$(SCENE).png
	$(BIN)/python -m examples.spring_mass --results results/$(SCENE).csv

test: fmus
	OMP_NUM_THREADS=1 $(BIN)/pytest -q

benchmarks: fmus
	OMP_NUM_THREADS=1 $(BIN)/python -m benchmarks.run_benchmarks

clean:
	rm -rf build results
