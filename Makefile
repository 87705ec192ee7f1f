# One-command set-up and checks. `make test` creates .venv, installs the project with its test extras and
# the client's npm dependencies, then runs ruff and every test.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP_STAMP := $(VENV)/.installed
NPM_STAMP := node_modules/.installed

DEMO_STUDY := study_server/demo/study.toml

.PHONY: translations setup wheel demo demo-report demo-power replication serve-replication test test-fast lint audit pytest serve bench clean

setup: $(PIP_STAMP) $(NPM_STAMP)

# The built-in demo study's model library (procedural meshes) and priors, the server's own for the AI2-THOR corpus
# (in var/): built when missing, and again when the code that makes them changes.
demo: setup
	$(BIN)/scenesuggest study prepare $(DEMO_STUDY)

serve: demo
	$(BIN)/scenesuggest study serve --host 127.0.0.1 --port 5000 --no-prepare

# pip speaks only of errors (-qq): its warnings about this machine's package indexes and setuptools' notes on
# editable installs are not what a first run needs to read.
$(PIP_STAMP): pyproject.toml
	@echo "installing the Python packages into $(VENV) (a few minutes the first time) …"
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@$(BIN)/python -m pip install -qq --upgrade pip
	@$(BIN)/python -m pip install -qq -e '.[test]'
	@touch $@

$(NPM_STAMP): package.json package-lock.json
	@echo "installing three.js and axe-core from npm (package-lock.json) …"
	@npm ci --no-audit --no-fund --loglevel=error
	@touch $@

# The wheel, with the three.js files the client imports (setup.py); built afresh, so that nothing an earlier
# build left in build/ comes along.
wheel: setup
	rm -rf build dist *.egg-info
	$(BIN)/python -m pip wheel --no-deps -qq -w dist .
	rm -rf build *.egg-info
	@ls dist/*.whl

# The participant pages' strings: extract them from the server's code and templates and bring every catalogue up
# to date (new strings appear untranslated in study_server/translations/<language>/LC_MESSAGES/messages.po; the
# tests fail until each is translated).
translations: $(PIP_STAMP)
	mkdir -p var
	$(BIN)/pybabel extract -F study_server/translations/babel.cfg --no-location --sort-output -o var/messages.pot .
	$(BIN)/pybabel update -i var/messages.pot -d study_server/translations --no-fuzzy-matching --ignore-obsolete -w 116

lint: $(PIP_STAMP)
	$(BIN)/ruff check .

# Known vulnerabilities in the Python and npm dependencies (skipped, with the reason, where the registries do
# not answer vulnerability queries).
audit: $(PIP_STAMP) $(NPM_STAMP)
	$(BIN)/python .ci/audit

# Every test: those without a browser on two processes (a test file each at a time, single-threaded BLAS, as in
# test-fast), then the browser tests, which drive Chromium (Firefox and WebKit on Xvfb) and a server of their own,
# one at a time.
PARALLEL := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/pytest -n 2 --dist loadfile
pytest: setup
	$(PARALLEL) -m "not browser"
	$(BIN)/pytest -m browser

test: demo lint audit pytest

# The inner loop: no browser, no PostgreSQL, no kill test (the whole suite is `make test`), on two processes (two
# processes of two BLAS threads each on two cores run slower than single-threaded BLAS).
test-fast: demo
	$(PARALLEL) -q -m "not browser and not postgresql and not slow"

# A study of the demo with 20 simulated participants, exported and analysed (var/demo-report/report/README.md).
DEMO_REPORT := var/demo-report
demo-report: demo
	rm -rf $(DEMO_REPORT) && mkdir -p $(DEMO_REPORT)
	SCENESUGGEST_INSTANCE=$(CURDIR)/$(DEMO_REPORT)/instance $(BIN)/scenesuggest study simulate --participants 20 --seed 0 \
		--db sqlite:///$(CURDIR)/$(DEMO_REPORT)/study.sqlite3
	SCENESUGGEST_INSTANCE=$(CURDIR)/$(DEMO_REPORT)/instance $(BIN)/scenesuggest study export --study demo \
		--db sqlite:///$(CURDIR)/$(DEMO_REPORT)/study.sqlite3 --out $(DEMO_REPORT)/export
	$(BIN)/scenesuggest analyze report --export $(DEMO_REPORT)/export --out $(DEMO_REPORT)/report

# How many participants the demo needs: power of every test at N = 10, 20, 40 from the demo report's pilot.
demo-power: demo-report
	$(BIN)/scenesuggest analyze power --export $(DEMO_REPORT)/export --participants 10,20,40 --studies 100

# The SceneSuggest replication (experiments/scenesuggest-2015): prepare its library, priors and targets from your
# copy of the Stanford Scene Database ($$SCENESUGGEST_STANFORD_DIR, default ../shared/data/stanford_scene_db);
# calibrate the simulated participants four times (calibration/<fold>.json: on `none` alone, with four refits on
# drawn cells for `study power`, and leaving each condition out in turn; each again only when the study, its
# priors, library, the simulation code or the paper's numbers changed) and
# measure what each condition can tell (calibration/identifiability.json); run 20 simulated participants with each
# calibration, export and analyse each run, run the `none` calibration's bots again with the learned engine serving
# the suggestions, and write the report and the comparison with the paper into experiments/scenesuggest-2015/results/.
REPLICATION := experiments/scenesuggest-2015
REPLICATION_RUN := var/experiments/scenesuggest-2015/run
REPLICATION_FOLDS := none none+basic none+full basic+full
SCENESUGGEST_STANFORD_DIR ?= $(CURDIR)/../shared/data/stanford_scene_db
REPLICATION_ENV = SCENESUGGEST_INSTANCE=$(CURDIR)/$(REPLICATION_RUN)/instance SCENESUGGEST_STUDIES=$(CURDIR)/$(REPLICATION)/study.toml
replication: setup
	SCENESUGGEST_STANFORD_DIR=$(SCENESUGGEST_STANFORD_DIR) $(BIN)/python $(REPLICATION)/prepare.py
	rm -rf $(REPLICATION_RUN) && mkdir -p $(REPLICATION_RUN)
	$(BIN)/python $(REPLICATION)/compare.py engines
	for fold in $(REPLICATION_FOLDS); do \
		DATABASE_URL=sqlite:///$(CURDIR)/$(REPLICATION_RUN)/calibrate.sqlite3 $(REPLICATION_ENV) $(BIN)/scenesuggest study \
			calibrate --on $$(echo $$fold | tr + ,) $$([ $$fold = none ] && echo --evaluations 500 --draws 4 || echo --evaluations 350) \
			--if-stale -o $(REPLICATION)/calibration/$$fold.json || exit 1; \
	done
	DATABASE_URL=sqlite:///$(CURDIR)/$(REPLICATION_RUN)/calibrate.sqlite3 $(REPLICATION_ENV) $(BIN)/scenesuggest study \
		calibrate --explain --start $(REPLICATION)/calibration/none.json --if-stale \
		-o $(REPLICATION)/calibration/identifiability.json
	rm -rf $(REPLICATION)/results/report
	for fold in $(REPLICATION_FOLDS); do \
		$(REPLICATION_ENV) $(BIN)/scenesuggest study simulate --participants 20 --seed 0 \
			--calibration $(REPLICATION)/calibration/$$fold.json --on $$(echo $$fold | tr + ,) \
			--db sqlite:///$(CURDIR)/$(REPLICATION_RUN)/study-$$fold.sqlite3 || exit 1; \
		$(REPLICATION_ENV) $(BIN)/scenesuggest study export --study scenesuggest-2015 \
			--db sqlite:///$(CURDIR)/$(REPLICATION_RUN)/study-$$fold.sqlite3 --out $(REPLICATION_RUN)/export-$$fold || exit 1; \
		$(BIN)/scenesuggest analyze report --export $(REPLICATION_RUN)/export-$$fold \
			--out $$([ $$fold = none ] && echo $(REPLICATION)/results/report || echo $(REPLICATION_RUN)/report-$$fold) || exit 1; \
	done
	SCENESUGGEST_INSTANCE=$(CURDIR)/$(REPLICATION_RUN)/instance SCENESUGGEST_STUDIES=$(CURDIR)/$(REPLICATION_RUN)/study-learned.toml \
		$(BIN)/scenesuggest study simulate --participants 20 --seed 0 --calibration $(REPLICATION)/calibration/none.json \
		--db sqlite:///$(CURDIR)/$(REPLICATION_RUN)/study-learned.sqlite3
	SCENESUGGEST_INSTANCE=$(CURDIR)/$(REPLICATION_RUN)/instance SCENESUGGEST_STUDIES=$(CURDIR)/$(REPLICATION_RUN)/study-learned.toml \
		$(BIN)/scenesuggest study export --study scenesuggest-2015 --db sqlite:///$(CURDIR)/$(REPLICATION_RUN)/study-learned.sqlite3 \
		--out $(REPLICATION_RUN)/export-learned
	$(BIN)/scenesuggest analyze report --export $(REPLICATION_RUN)/export-learned --out $(REPLICATION_RUN)/report-learned
	$(BIN)/python $(REPLICATION)/compare.py

# The replication study served for people (prepared first): http://127.0.0.1:5000/study/scenesuggest-2015/start?pid=…
serve-replication: setup
	SCENESUGGEST_STANFORD_DIR=$(SCENESUGGEST_STANFORD_DIR) $(BIN)/python $(REPLICATION)/prepare.py
	SCENESUGGEST_STUDIES=$(CURDIR)/$(REPLICATION)/study.toml $(BIN)/scenesuggest study serve --host 127.0.0.1 --port 5000 --no-prepare

bench: demo
	$(BIN)/python benchmarks/bench_corpus.py
	$(BIN)/python benchmarks/bench_suggest.py
	$(BIN)/python benchmarks/bench_ingest.py
	$(BIN)/python benchmarks/bench_pages.py
	$(BIN)/python benchmarks/bench_analysis.py
	$(BIN)/python benchmarks/bench_kill.py

clean:
	rm -rf $(VENV) node_modules .pytest_cache .ruff_cache var test-artifacts build dist
