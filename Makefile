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

.PHONY: demo test test-fast build lint clean extension test-blenders

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

# The fast tests on each Blender the manifest names, each in its own venv (.venv-bpyX.Y) with
# that release's bpy module from PyPI and the abi3 vplace wheel: `make test-blenders`, or
# `make test-blenders BLENDERS="4.2 5.2"`. bpy 4.2-5.0 are built for CPython 3.11, 5.2 for 3.13
# (with numpy 2: tests/requirements.txt's numpy pin is left out there).
BLENDERS ?= 4.2 4.5 5.0 5.2
BPY_4.2 := 4.2.23
BPY_4.5 := 4.5.15
BPY_5.0 := 5.0.1
BPY_5.2 := 5.2.3
PY_4.2 := python3.11
PY_4.5 := python3.11
PY_5.0 := python3.11
PY_5.2 := python3.13
NO_PIN_5.2 := numpy
TEST_WHEELS := target/wheels-test
TEST_WHEEL := $(TEST_WHEELS)/.stamp

$(TEST_WHEEL): $(NATIVE_SRC) $(DEPS)
	rm -f $(TEST_WHEELS)/vplace-*.whl
	VIRTUAL_ENV=$(abspath $(VENV)) PATH="$(abspath $(VENV))/bin:$$PATH" \
		maturin build --release --quiet -m rust/vplace-py/Cargo.toml -o $(TEST_WHEELS)
	touch $@

.PRECIOUS: .venv-bpy%/.deps-stamp .venv-bpy%/.native-stamp
.venv-bpy%/.deps-stamp: tests/requirements.txt
	@command -v $(PY_$*) >/dev/null || { echo "test-blenders: Blender $* needs $(PY_$*) on PATH"; exit 1; }
	rm -rf .venv-bpy$*
	$(PY_$*) -m venv .venv-bpy$*
	.venv-bpy$*/bin/python -m pip install --quiet --upgrade pip
	grep -v -E '^(bpy$(if $(NO_PIN_$*),|$(NO_PIN_$*)))==' tests/requirements.txt > .venv-bpy$*/requirements.txt
	.venv-bpy$*/bin/python -m pip install --quiet bpy==$(BPY_$*) -r .venv-bpy$*/requirements.txt
	touch $@

.venv-bpy%/.native-stamp: .venv-bpy%/.deps-stamp $(TEST_WHEEL)
	.venv-bpy$*/bin/python -m pip install --quiet --force-reinstall --no-deps $(TEST_WHEELS)/vplace-*.whl
	touch $@

test-blenders: $(foreach b,$(BLENDERS),.venv-bpy$(b)/.native-stamp)
	@set -e; for b in $(BLENDERS); do \
		echo "== Blender $$b (bpy $$(.venv-bpy$$b/bin/python -c 'import bpy; print(bpy.app.version_string)'))"; \
		.venv-bpy$$b/bin/python -m pytest tests -m "not slow" -q -p no:cacheprovider --tb=short; \
	done

# The four per-platform zips in dist/ (cross-compiled: installs the Rust targets, MinGW-w64 and
# zig when missing), then their checks, the Windows wheels under Wine included (set up once).
# Not part of `make test`: there tests/test_extension_zips.py skips until dist/ has the zips.
extension: build
	$(PY) addon/_build/build_extension.py --out dist
	$(PY) tests/windows_under_wine.py
	$(PY) -m pytest tests/test_extension_zips.py -q -rs

clean:
	rm -rf $(VENV) .venv-bpy* target out dist
