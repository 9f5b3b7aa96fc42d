# rosgate: `make run` starts the gateway with the embedded sim and the IDE; `make test` runs every test.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
ARGS   ?=

.PHONY: run test bench install install-test ide clean

$(PY):
	$(PYTHON) -m venv $(VENV) || { echo "python3 -m venv failed: install python3-venv (apt-get install python3-venv)"; exit 1; }
	$(PY) -m pip install -q --upgrade pip

$(VENV)/.installed: pyproject.toml | $(PY)
	$(PY) -m pip install -q -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml $(VENV)/.installed
	$(PY) -m pip install -q -e '.[test,bench]'
	touch $@

ide/vendor/.built: ide/package.json ide/package-lock.json
	@command -v npm >/dev/null || { echo "npm is missing: install nodejs and npm (apt-get install nodejs npm)"; exit 1; }
	cd ide && npm ci --no-audit --no-fund && npm run build
	touch $@

tests/node/node_modules/.installed: tests/node/package.json tests/node/package-lock.json
	cd tests/node && npm ci --no-audit --no-fund
	touch $@

install: $(VENV)/.installed
install-test: $(VENV)/.installed-test
ide: ide/vendor/.built

run: install ide
	$(PY) -m gateway --robot turtlesim $(ARGS)

test: install-test ide tests/node/node_modules/.installed
	$(PY) -m pytest -q tests
	cd tests/node && node --test

bench: install-test
	$(PY) -m tests.bench $(ARGS)

clean:
	rm -rf $(VENV) ide/node_modules ide/vendor
