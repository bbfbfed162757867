# robotgen: developer entry points. `make install test` is what CI runs.
PYTHON ?= python3
SPECS := $(wildcard specs/*.yaml)

.PHONY: install test demo bench generated clean

install:
	$(PYTHON) -m pip install --quiet --upgrade pip
	$(PYTHON) -m pip install --quiet -e '.[test]'

test:
	$(PYTHON) -m pytest -q

demo:
	$(PYTHON) examples/demo.py

bench:
	$(PYTHON) -m pip install --quiet cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0  # headers for bench/pinocchio_harness.cpp (the pin wheel has neither)
	$(PYTHON) bench/run.py
	$(PYTHON) bench/scaling.py  # build s and ns per call vs dof: chains of 2..30 links, a humanoid tree (~5 min)

# Rebuild the committed generated/ tree (sources and manifests; the compiled module is
# built too but not committed). tests/test_generated.py checks it is never stale.
generated:
	@for spec in $(SPECS); do $(PYTHON) -m robotgen build $$spec || exit 1; done

clean:
	rm -rf build *.egg-info bench/out .pytest_cache
