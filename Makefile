# Each target bootstraps .venv itself: a fresh machine needs only python3.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# `make test` needs the dev, cluster (Dask) and gym extras; `make bench` also the
# bench extra (highway-env, the reference implementation it compares against).
STAMP_BASE  := $(VENV)/.installed-dev
STAMP_BENCH := $(VENV)/.installed-bench

.PHONY: demo test lint bench clean

$(PY):
	$(PYTHON) -m venv $(VENV)

$(STAMP_BASE): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev,cluster,gym]"
	touch $@

$(STAMP_BENCH): $(STAMP_BASE)
	$(PY) -m pip install --quiet -e ".[dev,cluster,gym,bench]"
	touch $@

demo: $(STAMP_BASE)
	$(VENV)/bin/minimaxplan demo

test: $(STAMP_BASE)
	$(PY) -m pytest -n 2 -q

# ruff (lint rules and formatting) and mypy on the package; .ci/run runs it before the tests.
# mypy reads the package through a link named minimaxplan: the repository root is the
# package (package-dir "."), and the checkout's own folder name may not be a valid one.
lint: $(STAMP_BASE)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	rm -rf .lint && mkdir .lint && ln -s .. .lint/minimaxplan
	MYPYPATH=.lint $(VENV)/bin/mypy -p minimaxplan

bench: $(STAMP_BENCH)
	$(PY) benchmarks/run_all.py

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis .benchmarks
