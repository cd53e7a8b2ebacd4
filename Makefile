# One command sets up and runs the main job; one sets up and passes the tests.
#   make run       -> creates .venv with Python >= 3.12 if missing, installs, runs `scioc run`
#   make test      -> same setup, then the fast test tier (every test not marked `validation`), in two pytest-xdist
#                     workers, each test file whole on one worker (its module fixtures built once)
#   make validate  -> same setup, then the validation tier; writes docs/validation.md
VENV ?= .venv
# Python >= 3.12 (PyMC 6). Tried in order: $(PYTHON) if given, python3.12/3.13 on PATH, pyenv installs.
PYTHON ?= $(shell for p in python3.12 python3.13 $$HOME/.pyenv/versions/3.12*/bin/python3 $$HOME/.pyenv/versions/3.13*/bin/python3 /usr/bin/python3; do \
	$$p -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)' >/dev/null 2>&1 && { echo $$p; break; }; done)
STAMP := $(VENV)/.installed

.PHONY: setup run test validate browser bench bench-angles calibrate power humans clean

$(STAMP): pyproject.toml
	@test -n "$(PYTHON)" || { echo "error: no Python >= 3.12 found (PyMC 6 needs it); pass PYTHON=/path/to/python3.12" >&2; exit 1; }
	@test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP)

run: $(STAMP)
	$(VENV)/bin/scioc run

test: $(STAMP)
	$(VENV)/bin/python -m pytest tests -n 2 --dist loadfile -m "not validation"

# Reduced-size statistical studies, SBC smoke runs, delayed fits and recovery; their report, stamped
# with the commit, goes to docs/validation.md. One process (no -n): the `measured` fixture keeps its numbers in
# the process that runs the test, where the report is written.
validate: $(STAMP) browser
	$(VENV)/bin/python -m pytest tests -m validation --validation-report=docs/validation.md

# Headless Chromium for the report's browser test (the Debian package; CI runs as root).
browser:
	@command -v chromium >/dev/null || command -v chromium-browser >/dev/null || { \
		echo "installing chromium (Debian package) for the report's browser test"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; }

bench: $(STAMP)
	$(VENV)/bin/scioc bench --report docs/validation.md

# The paper's design, angles only, at the paper's size: identifying every unit from its angles, and the
# delayed and max-ent fits through the angle likelihood for two humans the max-ent model does not describe, each
# with and without a change of cost (about 3 hours); its own section of docs/validation.md.
bench-angles: $(STAMP)
	$(VENV)/bin/scioc bench --parts delayed,fit_angles --report docs/validation.md

# Full simulation-based calibration (unit: 1000 replications, study: 200, each with its
# negative control), then the report again with its results.
calibrate: $(STAMP)
	$(VENV)/bin/scioc calibrate --level unit
	$(VENV)/bin/scioc calibrate --level study
	$(VENV)/bin/scioc report reports/default-study

# Model adequacy: the verdict's false-alarm rate and power over 20 simulated studies per
# simulated human (reports/power/power.json; the report's adequacy section reads it).
power: $(STAMP)
	$(VENV)/bin/scioc power --studies 20 --out reports/power

# The whole workflow (fit included) on one study of each simulated human whose cost does not
# change between MC and SC (reports/human-NAME/). A failing adequacy verdict exits 1 by
# design, so only other failures stop the loop.
humans: $(STAMP)
	for h in maxent delay lag coloured combined crossover; do \
		$(VENV)/bin/scioc run --human $$h --beta 0 --human-model maxent --name human-$$h || test $$? -eq 1 || exit 1; \
	done

clean:
	rm -rf $(VENV)
