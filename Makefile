# The two commands of the README: `make demo` and `make test`.
# Both create .venv from pyproject.toml and build the FMUs on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
BIN = $(VENV)/bin
SCENE ?= spring_mass_nonlinear

.PHONY: demo test quick quick-rest quick-beside test-serial test-beside test-rest fmus browser screenshots figures benchmarks baselines clean

$(VENV)/installed: pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,serve]'
	touch $@

fmus: $(VENV)/installed
	$(BIN)/dsim build-fmus

demo: fmus
	$(BIN)/dsim run build/ssp/$(SCENE).ssp --out results/$(SCENE).csv --plot results/$(SCENE).png
	$(BIN)/python -m examples.spring_mass --results results/$(SCENE).csv

# The test tiers (README, "Tests"; docs/ci.md): markers in pyproject.toml, assigned by
# tests/conftest.py.  `make test` runs every test in three pytest processes at once and
# prints where the time goes: each process's slowest tests (--durations), then its wall
# and CPU seconds by folder and file (each test's CPU recorded by tests/conftest.py in
# results/junit-*.xml, summed by tests/support/timing.py).  The Ray tests (BESIDE) in
# one, into results/test-beside.log; the others in two, split by folder (REST_B into
# results/test-rest-b.log, the rest on the terminal).  The Ray process waits on Ray more
# than it computes (a third of a core); the two others run at the lowest priority (nice
# 19), so they fill the cores it leaves idle with the least slowing of what it waits on.  They share
# nothing (the Ray tests, and only they, start or join Ray instances; the wheel test
# works on a copy of the checkout; dsim serve binds free ports).  `make test-serial` is
# the same suite in one process.
PYTEST = OMP_NUM_THREADS=1 $(BIN)/pytest
NICE_PYTEST = OMP_NUM_THREADS=1 nice -n 19 $(BIN)/pytest
QUICK = not (wheel or kernels or ray or browser or fuzz or slow)
BESIDE = ray
REST_B = tests/fmus tests/checks tests/sweeps tests/house tests/tools tests/recording

test: fmus browser
	@mkdir -p results && rm -f results/test-*.log results/junit-*.xml
	@$(MAKE) --no-print-directory -j3 -k test-beside test-rest test-rest-b; status=$$?; \
	  for half in rest-b beside; do \
	    echo "=== the tests of results/test-$$half.log (run at the same time):"; \
	    cat results/test-$$half.log; done; \
	  echo "=== where the time went (seconds per process, folder and file):"; \
	  $(BIN)/python -m tests.support.timing results/junit-rest.xml results/junit-rest-b.xml \
	    results/junit-beside.xml; exit $$status

# the three parts of `make test` (they expect its set-up: use `make test`)
test-rest:
	$(NICE_PYTEST) -q -rs --durations=20 --junitxml=results/junit-rest.xml \
	  -m "not ($(BESIDE))" tests $(REST_B:%=--ignore=%)
test-rest-b:
	@echo "make: the tests of $(REST_B) -m 'not ($(BESIDE))' run beside, into results/test-rest-b.log"
	@$(NICE_PYTEST) -q -rs --durations=20 --junitxml=results/junit-rest-b.xml \
	  -m "not ($(BESIDE))" -p no:cacheprovider \
	  $(REST_B) >results/test-rest-b.log 2>&1
test-beside:
	@echo "make: the tests -m '$(BESIDE)' run beside, into results/test-beside.log"
	@$(PYTEST) -q -rs --durations=15 --junitxml=results/junit-beside.xml -m "$(BESIDE)" \
	  -p no:cacheprovider >results/test-beside.log 2>&1

test-serial: fmus browser
	$(PYTEST) -q -rs --durations=25

# the fast tier: everything but the wheel, kernel, Ray, browser, fuzz and slow tests, in
# two pytest processes side by side as `make test` runs (the folders of QUICK_BESIDE in
# one, into results/quick-beside.log, every other folder in the second)
QUICK_BESIDE = tests/fmus tests/reading tests/recording tests/planning tests/distributed \
               tests/checks tests/sweeps tests/house tests/tools
quick: fmus
	@mkdir -p results && rm -f results/quick-beside.log
	@$(MAKE) --no-print-directory -j2 -k quick-beside quick-rest; status=$$?; \
	  echo "=== the quick tests of $(QUICK_BESIDE), from results/quick-beside.log:"; \
	  cat results/quick-beside.log; exit $$status

# the two halves of `make quick` (they expect its set-up: use `make quick`)
quick-rest:
	$(PYTEST) -q -rs --durations=10 -m "$(QUICK)" tests $(QUICK_BESIDE:%=--ignore=%)
quick-beside:
	@$(PYTEST) -q -rs --durations=10 -m "$(QUICK)" -p no:cacheprovider $(QUICK_BESIDE) \
	  >results/quick-beside.log 2>&1

# Debian packages some tests use, installed when missing and allowed (best effort: without
# them those tests are skipped, and pytest -rs says so): Chromium for dsim serve's browser
# tests, valgrind for the test of a pythonfmu FMU's process exit
# (tests/running/test_pythonfmu_exit.py).
# $(call debian,PACKAGE,COMMANDS): install PACKAGE unless one of COMMANDS is on the PATH
debian = for c in $(2); do command -v $$c >/dev/null 2>&1 && exit 0; done; \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(1) >/dev/null || true; \
	  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then \
	    sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(1) >/dev/null || true; \
	  else echo "make: no $(1), and no way to install it here: the tests that need it will be skipped"; fi
browser:
	@$(call debian,chromium,chromium chromium-browser)
	@$(call debian,valgrind,valgrind)

# the screenshots of docs/serve.md, made by the browser tests
screenshots: fmus browser
	DSIM_SCREENSHOTS=docs/serve OMP_NUM_THREADS=1 $(BIN)/pytest -q -rs tests/serve/test_serve_browser.py

# docs/figures/: one `dsim run --plot` per kind of shipped scene (SCENE:STOP, shortened where
# a whole run takes minutes), the plots the README and docs/results.md show
FIGURES = spring_mass_nonlinear:10 chain_10:1 crank_slider_rigid:2 four_bar_singular_flexible:2 \
          four_post_fixed:1 frame_split:0.05
figures: fmus
	@mkdir -p docs/figures results/figures
	@for item in $(FIGURES); do scene=$${item%%:*}; stop=$${item##*:}; \
	  echo "figure docs/figures/$$scene.png"; \
	  OMP_NUM_THREADS=1 $(BIN)/dsim run build/ssp/$$scene.ssp --stop $$stop --quiet \
	    --out results/figures/$$scene.csv --plot docs/figures/$$scene.png || exit 1; done

benchmarks: fmus
	OMP_NUM_THREADS=1 $(BIN)/python -m benchmarks.run_benchmarks

# dsim's own regression baselines regenerated, with the kernel study that sets their
# bands' floor (docs/ci.md): after a change that moves results on purpose
baselines: fmus
	OMP_NUM_THREADS=1 $(BIN)/dsim regress build/ssp --baselines regression/baselines --update

clean:
	rm -rf build results
