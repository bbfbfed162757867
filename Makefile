# robotgen: developer entry points. `make install test` is what CI runs (.ci/run adds the
# reproducibility variants).
PYTHON ?= python3
# OpenBLAS kernels to build under (test-reproducible): those this CPU can run
CORETYPES ?= $(shell $(PYTHON) -c "from tests.emit.test_reproducible import coretypes; print(' '.join(coretypes()))" 2>/dev/null)

.PHONY: install test test-quick test-slow lint test-reproducible demo controller bench golden clean
# A first check in under 3 minutes: each layer's fast tests (the spec front end and its
# messages, dynamics against closed forms and Pinocchio, the emitted module, run-time
# parameters and the hand controllers' first step, the command line). `make test` runs all.
QUICK_TESTS ?= tests/spec tests/dynamics/test_closed_form.py tests/dynamics/test_properties.py \
	tests/dynamics/test_puma_pinocchio.py tests/dynamics/test_urdf_pinocchio.py tests/primitives/test_primitives.py \
	tests/emit/test_emit.py tests/emit/test_parameter_bounds.py tests/control/test_hand_start.py tests/cli/test_cli.py \
	tests/cli/test_hints.py

# pytest-xdist: a worker per core, each test file whole to one worker (its module's builds made once)
PYTEST_JOBS ?= -n auto --dist loadfile

install:
	$(PYTHON) -m pip install --quiet --upgrade pip
	$(PYTHON) -m pip install --quiet -e '.[test]'

test: lint
	$(PYTHON) -m pytest -q $(PYTEST_JOBS)

test-quick: lint
	$(PYTHON) -m pytest -q $(PYTEST_JOBS) $(QUICK_TESTS)

# the long runs (pytest -m slow): 10^4 Hypothesis mutants of the example specs (~10 min), every URDF
# of example-robot-data and pybullet_data against Pinocchio and docs/robots.md (~2 min), and the
# compiles that repeat a faster case's (more Cortex-M, sanitizer and float builds, Pinocchio-cg)
test-slow:
	$(PYTHON) -m pytest -q $(PYTEST_JOBS) -m slow

# ruff with pyproject.toml's rules: pyflakes, pycodestyle, import order, bugbear, pyupgrade, and D1 on
# robotgen/ (every public module, class, function and method has a docstring; tests/, bench/ and
# examples/ are exempt); then mypy on robotgen/ ([tool.mypy]: the node union narrowed by type).
# `ruff format --check` holds every Python file to ruff's formatter. `make test` and `make test-quick`
# run it first.
lint:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m ruff format --check .
	$(PYTHON) -m mypy

# The golden outputs, rebuilt under every OpenBLAS kernel this CPU runs: the emitted C and
# manifests must not change by a bit.
test-reproducible:
	@for kind in $(CORETYPES); do \
	  echo "OPENBLAS_CORETYPE=$$kind"; \
	  OPENBLAS_CORETYPE=$$kind $(PYTHON) -m pytest -q -p no:cacheprovider tests/emit/test_golden.py || exit 1; \
	done

demo:
	$(PYTHON) examples/demo.py

# examples/controller: fixed-rate servo loops in C around the emitted code (PUMA 560 computed
# torque, the Styx hand tree); run them with --rate HZ --cycles N for jitter and servo times;
# styx_multirate runs the multi-rate hand's groups (--schedule threads|cyclic, --cycles N).
controller:
	$(MAKE) -C examples/controller ROBOTGEN="$(PYTHON) -m robotgen"

# The code-generating peers (bench/code_generators.py): Pinocchio's code generation needs CppAD and
# CppADCodeGen (headers); casadi_kin_dyn pins an older Pinocchio and CasADi, so it gets a virtual
# environment of its own in bench/out/. A peer that cannot be installed is reported and left out.
CASADI_KIN_DYN_ENV ?= bench/out/casadi-kin-dyn
bench:
	$(PYTHON) -m pip install --quiet cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0  # headers for bench/pinocchio_harness.cpp (the pin wheel has neither)
	$(PYTHON) -m pip install --quiet cmeel-cppad==20250000.2 cmeel-cppadcodegen==2.4.3 \
	  || echo "bench: CppAD / CppADCodeGen not installed: Pinocchio's code generation is left out"
	($(PYTHON) -m venv $(CASADI_KIN_DYN_ENV) && $(CASADI_KIN_DYN_ENV)/bin/python -m pip install --quiet \
	  cmeel-casadi-kin-dyn==1.6.14) || echo "bench: casadi_kin_dyn not installed: it is left out"
	$(PYTHON) bench/run.py
	$(PYTHON) bench/code_generators.py  # the peers' generated C vs robotgen's on the UR5, Panda, iiwa (~10 min the first time)
	$(PYTHON) bench/controllers.py  # servo step with run-time vs folded gains; hand controllers in C vs CasADi
	$(PYTHON) bench/scaling.py  # build s and ns per call vs dof: chains of 2..30 links, a humanoid tree (~5 min)
	$(PYTHON) bench/batch.py  # states/s of the _batch entry points (SIMD across states) against a loop of single calls

# Refresh tests/golden/ (every spec's manifest, the small specs whole); tests/emit/test_golden.py
# checks that a fresh build equals it.
golden:
	$(PYTHON) tests/golden/refresh.py

clean:
	rm -rf build *.egg-info bench/out .pytest_cache .mypy_cache generated
	$(MAKE) -C examples/controller clean
