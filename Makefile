# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test install clean

install: $(STAMP)

# constraints.txt pins the versions the test suite was run with (numbers reproduce bit for bit).
# The compiled kernels are compiled as part of the install (cached beside the source, about a minute
# on two cores), as pip compiles the bytecode: no first toolpath, diagnosis or test run waits for them.
$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints.txt -e '.[dev]'
	$(PY) -m vjm.kernels
	touch $(STAMP)

BIN    := $(VENV)/bin
OUT    := out
PUU    := data/orthoglide/puu.yaml
PRPAR  := data/orthoglide/prpar.yaml
LINKS  := --foot $(OUT)/foot/result.json

# The whole path on the default example: link CAD -> 6x6 compliances -> machine stiffness
# (maps, seed Table 1) -> a hidden effect found in simulated measurements -> a pocket's deflection
# and its compensated G-code; a serial robot's stiffness and self-weight sag over its joint space, and
# a square pocket pass milled by it, compensated for the cutting force and its own weight.
demo: $(STAMP)
	$(BIN)/linkfea compute orthoglide_foot --out $(OUT)/foot/result.json
	$(BIN)/linkfea compute parallelogram_bar --out $(OUT)/bar/result.json
	$(BIN)/linkfea compute parallelogram_bar --param height=16 --param boss_height=20 --out $(OUT)/leg/result.json
	$(BIN)/vjm table1 $(PUU) $(PRPAR) $(LINKS) --leg $(OUT)/leg/result.json --bar $(OUT)/bar/result.json
	$(BIN)/vjm map $(PUU) --grid 41 --slice z=0 $(LINKS) --leg $(OUT)/leg/result.json --out $(OUT)/maps/puu
	$(BIN)/vjm map $(PRPAR) --grid 41 --slice z=0 $(LINKS) --leg $(OUT)/bar/result.json --out $(OUT)/maps/prpar
	$(BIN)/vjm map data/machines/hexapod_6ups.yaml --grid 41 --slice z=550 --orientation 0,0,0.1 --out $(OUT)/maps/hexapod
	$(BIN)/vjm simulate $(PUU) --effect clearance:backlash=0.003 --poses random:30 --loads axes:100 \
	    --noise-t 0.001 --seed 1 --out $(OUT)/diagnose/measurements.csv
	$(BIN)/vjm diagnose $(PUU) $(OUT)/diagnose/measurements.csv --out $(OUT)/diagnose/report
	$(BIN)/vjm path $(PUU) data/toolpaths/pocket.nc $(LINKS) --leg $(OUT)/leg/result.json --tool 0,0,-60 \
	    --kc 700 --feed-per-tooth 0.05 --depth 1 --width 8 --split-moves --workers 2 --out $(OUT)/path
	$(BIN)/vjm stiffness data/robots/ur10/ur10.yaml --q 0,-1.2,1.5,-1.9,-1.57,0 --self-weight
	$(PY) docs/examples/serial_robot.py
	$(BIN)/vjm path data/robots/ur10/ur10.yaml data/toolpaths/robot_square.nc --tool 0,0,150 --kc 700 \
	    --feed-per-tooth 0.05 --depth 2 --width 8 --split-moves --step 5 --out $(OUT)/robot_path

# Lint and type-check (ruff, mypy) while the docs site is built beside them (strict: a broken link or a
# stale reference fails; output in .cache/site, log in .cache/mkdocs.log, shown if it fails), then the
# suite.  Meanwhile the compiled kernels are loaded, or compiled again where a source changed since the
# install (python -m vjm.kernels, log in .cache/kernels.log), so that the two test workers load them from
# the cache instead of each compiling them on first use; should that fail, the tests report why.  One BLAS
# thread per test worker: two workers on two cores, each with two BLAS threads, wait on each other.
test: $(STAMP)
	@mkdir -p .cache
	$(PY) -m vjm.kernels > .cache/kernels.log 2>&1 & kpid=$$!; \
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict > .cache/mkdocs.log 2>&1 & dpid=$$!; \
	$(BIN)/ruff check src tests docs/examples docs/tools && $(BIN)/mypy src; rc=$$?; \
	wait $$dpid || { cat .cache/mkdocs.log; rc=1; }; \
	wait $$kpid || cat .cache/kernels.log; exit $$rc
	DOCS_SITE=$(CURDIR)/.cache/site OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest -n 2 --dist loadfile --durations=15

clean:
	rm -rf out .cache
