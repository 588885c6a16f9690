# Every target installs what it needs into .venv first; `make test` is what CI runs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
QC_VENV := .venv-qc
QC_STAMP := $(QC_VENV)/.installed
NETS := 4way-stop t-stop y-uncontrolled 4way-signal t-signal crosswalk-stop crosswalk-signal

.PHONY: help install system-tools test test-fast docs lint format nets run demo openapi bench bench-api bench-jobs \
	bench-generator bench-variety bench-pedestrians bench-reliability campaign-curve \
	coverage clean

help:
	@echo "make run      serve the HTTP API on http://127.0.0.1:8000 (/docs, results at /ui/)"
	@echo "make test     install into .venv (Chromium and jq too, as root), build the docs and run every test"
	@echo "make test-fast   every test module but the slow ones (about 2 minutes): the edit loop"
	@echo "make docs     build the documentation site into site/ (strict); .venv/bin/mkdocs serve to browse it"
	@echo "make openapi  regenerate openapi/openapi.json from the app"
	@echo "make lint     ruff and mypy --strict"
	@echo "make nets     rebuild sumo_nets/*.net.xml from their plain-XML sources"
	@echo "make bench    time the checker, the RSS guard, the generator, the API and batch jobs (docs/benchmarks.md)"
	@echo "make bench-generator   only the generator: targets, variety, chain growth, Step 2 theories"
	@echo "make bench-variety     distinct extensions, count 10, against random search, chains to depth 8"
	@echo "make bench-pedestrians  one new pedestrian on every walk, mixed chains of cars and people"
	@echo "make bench-api / bench-jobs   one of those benchmarks"
	@echo "make bench-reliability   hostile requests and 30 MB documents against a server (docs/reliability.md)"
	@echo "make demo     describe the 4-way stop, write a test-case, drive and judge an ego"
	@echo "make coverage extend every conflicting route pair of the bundled intersections"
	@echo "make campaign-curve  failure rate by level of five controllers (docs/campaigns.md)"

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP) $(QC_STAMP)

# The ASAM Quality Checker bundles (OpenSCENARIO XML and OpenDRIVE, with their XSD schema
# checks) in a venv of their own: asam-qc-opendrive pins numpy < 2, which the service does
# not. The export tests run them as commands, the way a user does (docs/export.md).
$(QC_STAMP):
	$(PYTHON) -m venv $(QC_VENV)
	$(QC_VENV)/bin/pip install --quiet asam-qc-openscenarioxml asam-qc-opendrive asam-qc-framework
	touch $(QC_STAMP)

# The OpenAPI UI test drives Debian's Chromium, the curl examples of docs/http-api.md use jq;
# both are installed here when missing (as root; otherwise the message says what to install).
SYSTEM_TOOLS := chromium jq
system-tools:
	@missing=""; for tool in $(SYSTEM_TOOLS); do command -v $$tool >/dev/null || \
		missing="$$missing $$tool"; done; [ -z "$$missing" ] || { [ "$$(id -u)" = 0 ] && \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing \
		>/dev/null; } || echo "make: missing:$$missing (install Debian's packages)"

# three test processes on two cores: many tests wait (servers starting, workers killed and
# restarted, leases running out), and a third process computes meanwhile
TEST_PROCESSES ?= 3

test: $(STAMP) $(QC_STAMP) system-tools docs
	$(BIN)/pytest -n $(TEST_PROCESSES)

# the edit loop: every module but the slow ones (pytest -m slow: servers, browsers, SUMO on
# real maps, campaigns), in about 2 minutes; `make test` before you push
test-fast: $(STAMP) $(QC_STAMP) system-tools
	$(BIN)/pytest -n $(TEST_PROCESSES) -m "not slow"

# the documentation site (mkdocs.yml, docs/) into site/; strict: a warning, such as a broken
# link or anchor, fails the build. `$(BIN)/mkdocs serve` serves it while you edit.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

lint: $(STAMP)
	$(BIN)/ruff check service tests bench docs/hooks
	$(BIN)/ruff format --check service tests bench docs/hooks
	$(BIN)/mypy
	$(BIN)/mypy --strict docs/hooks

format: $(STAMP)
	$(BIN)/ruff check --fix service tests bench docs/hooks
	$(BIN)/ruff format service tests bench docs/hooks

nets: $(STAMP)
	cd sumo_nets && for net in $(NETS); do ../$(BIN)/netconvert -c $$net.netccfg || exit 1; done

run: $(STAMP)
	$(BIN)/scengen serve --host 127.0.0.1 --port 8000

openapi: $(STAMP)
	$(BIN)/python -m service.api.openapi openapi/openapi.json

demo: $(STAMP)
	$(BIN)/scengen intersection 4way-stop
	$(BIN)/scengen new 4way-stop --ego S2C_1:C2W_1 -o /tmp/scengen-demo.json
	$(BIN)/scengen drive /tmp/scengen-demo.json --json > /tmp/scengen-demo-cruise.json
	$(BIN)/scengen drive /tmp/scengen-demo.json
	$(BIN)/scengen check /tmp/scengen-demo.json --ego /tmp/scengen-demo-cruise.json \
		--controller cruise; echo "scengen check exited with $$? (1: the ego failed)"

bench: $(STAMP)
	$(BIN)/pip install --quiet -e '.[test,bench]'
	$(BIN)/python -m bench.bench_check
	$(BIN)/python -m bench.bench_rss
	$(BIN)/python -m bench.bench_replays
	$(BIN)/python -m bench.bench_cosim
	$(BIN)/python -m bench.bench_generate
	$(BIN)/python -m bench.bench_variety
	$(BIN)/python -m bench.bench_chains
	$(BIN)/python -m bench.bench_ordering
	$(BIN)/python -m bench.bench_pedestrians
	$(BIN)/python -m bench.bench_api
	$(BIN)/python -m bench.bench_jobs
	$(BIN)/python -m bench.bench_steps
	$(BIN)/python -m bench.bench_hostile
	$(BIN)/python -m bench.bench_large

bench-generator: $(STAMP)
	$(BIN)/pip install --quiet -e '.[test,bench]'
	$(BIN)/python -m bench.bench_generate
	$(BIN)/python -m bench.bench_variety
	$(BIN)/python -m bench.bench_chains
	$(BIN)/python -m bench.bench_ordering

# The variety measurements: variety, count 10 against one, distinct extensions per
# CPU-second against random search, and chain growth on these junctions.
VARIETY_CHAINS := 4way-stop t-stop y-uncontrolled 4way-signal t-signal "Town05 396 as allway_stop"
bench-variety: $(STAMP)
	$(BIN)/pip install --quiet -e '.[test,bench]'
	$(BIN)/python -m bench.bench_variety
	$(BIN)/python -m bench.bench_chains --only $(VARIETY_CHAINS)

bench-pedestrians: $(STAMP)
	$(BIN)/python -m bench.bench_pedestrians

campaign-curve: $(STAMP)
	$(BIN)/python -m bench.campaign_curve

bench-api: $(STAMP)
	$(BIN)/python -m bench.bench_api

bench-jobs: $(STAMP)
	$(BIN)/python -m bench.bench_jobs
	$(BIN)/python -m bench.bench_steps

bench-reliability: $(STAMP)
	$(BIN)/python -m bench.bench_hostile
	$(BIN)/python -m bench.bench_large

coverage: $(STAMP)
	$(BIN)/python -m bench.coverage

clean:
	rm -rf $(VENV) $(QC_VENV) .pytest_cache .mypy_cache .ruff_cache site
