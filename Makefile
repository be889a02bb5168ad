# The two commands of the README: `make demo` and `make test`. Each creates or reuses .venv,
# installs the pinned Python requirements, builds the Rust extension in release mode, then runs.
# Stamps make a second run skip what is already current.
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
DEPS := $(VENV)/.deps-stamp
NATIVE := $(VENV)/.native-stamp
NATIVE_SRC := $(shell find rust -name '*.rs' -o -name 'Cargo.toml' -o -name 'pyproject.toml') Cargo.toml Cargo.lock

.PHONY: demo test test-fast build lint clean extension

$(PY):
	$(PYTHON) -m venv $(VENV)

$(DEPS): tests/requirements.txt | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r tests/requirements.txt
	touch $@

$(NATIVE): $(NATIVE_SRC) $(DEPS)
	VIRTUAL_ENV=$(abspath $(VENV)) PATH="$(abspath $(VENV))/bin:$$PATH" \
		maturin develop --release --quiet -m rust/vplace-py/Cargo.toml
	touch $@

build: $(NATIVE)

demo: build
	$(PY) -m addon.cli demo --scene cornell --out out/cornell
	$(PY) -m addon.cli demo --scene sponza --out out/sponza --no-eevee

lint: build
	cargo fmt --all --check
	cargo clippy --workspace --all-targets --quiet -- -D warnings
	$(VENV)/bin/ruff check addon tests rust/vplace-py/python
	$(VENV)/bin/ruff format --check addon tests rust/vplace-py/python

test: lint
	cargo test --quiet
	$(PY) -m pytest tests

test-fast: build
	$(PY) -m pytest tests -m "not slow"

# The four per-platform zips in dist/ (cross-compiled: installs the Rust targets, MinGW-w64 and
# zig when missing), then their checks, the Windows wheels under Wine included (set up once).
# Not part of `make test`: there tests/test_extension_zips.py skips until dist/ has the zips.
extension: build
	$(PY) addon/_build/build_extension.py --out dist
	$(PY) tests/windows_under_wine.py
	$(PY) -m pytest tests/test_extension_zips.py -q -rs

clean:
	rm -rf $(VENV) target out dist
