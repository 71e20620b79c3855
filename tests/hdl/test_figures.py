"""lost.hdl.flow.figures: the FPGA figures as a versioned CSV, appended by the flow, the page's table made from it."""

import json

import pytest

from lost.hdl.flow import figures, synth

ENTRY = {
    "name": "window_l1_external_20x20_4x4", "variant": "window", "lanes": 1, "memory": "external",
    "map_shape": [20, 20], "patch_shape": [4, 4], "cycles": 500, "lut_mapper": "abc", "routed": True,
    "router": "router2", "seconds": 500 / 100e6,
    "result": {"seed": 2, "target_mhz": 250.0, "fmax_mhz": 100.04, "lut4": 8000, "ff": 9000, "ebr": 3, "dsp": 4,
               "lut4_available": 83640, "seconds": 612.5},
}


def test_a_routed_entry_becomes_a_row_and_reads_back(tmp_path):
    path = tmp_path / "figures.csv"
    row = figures.row_of(ENTRY, commit="abc1234", date="2026-11-29")
    figures.append(row, path)
    figures.append(row | {"commit": "def5678", "fmax_mhz": 99.0}, path)
    rows = figures.read(path)
    assert [r["commit"] for r in rows] == ["abc1234", "def5678"]
    assert rows[0]["map"] == "20x20" and rows[0]["correlation_ms"] == "0.005" and rows[0]["route_seconds"] == "612.5"
    assert figures.recorded(rows, row) and not figures.recorded(rows, row | {"seed": 3})
    # The latest row of each build makes the table.
    (latest,) = figures.latest(rows)
    assert latest["commit"] == "def5678"
    assert "| window | 1 | 20x20 | external | 99.0 | 8000 (10 %) |" in figures.markdown_table([latest])


def test_bad_rows_and_files_are_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="was not placed and routed"):
        figures.row_of(ENTRY | {"routed": False}, commit="x")
    with pytest.raises(ValueError, match="missing \\['note'\\]"):
        figures.append({field: 1 for field in figures.FIELDS if field != "note"}, tmp_path / "f.csv")
    other = tmp_path / "other.csv"
    other.write_text("date,fmax\n2026-01-01,1\n")
    with pytest.raises(ValueError, match="other.csv: the header is"):
        figures.read(other)


def test_the_page_table_is_replaced_between_its_markers(tmp_path):
    page = tmp_path / "fpga.md"
    page.write_text(f"# FPGA\n\nbefore\n{figures.BEGIN}\nold table\n{figures.END}\nafter\n")
    figures.update_page(page, [figures.row_of(ENTRY, commit="abc1234", date="2026-11-29")])
    text = page.read_text()
    assert "old table" not in text and "before" in text and "after" in text and "| abc1234 | 2026-11-29 |" in text
    page.write_text("no markers\n")
    with pytest.raises(ValueError, match="no <!-- figures:begin -->"):
        figures.update_page(page, [])


def test_the_shipped_figures_parse_and_the_page_holds_their_table():
    rows = figures.read()
    assert rows and all(row["commit"] for row in rows)
    page = (figures.CHECKOUT / "docs" / "fpga.md").read_text()
    assert figures.markdown_table(figures.latest(rows)) in page


def test_the_flow_appends_each_placed_build_once(tmp_path, monkeypatch):
    def fake_build(config, out_dir, *, seeds, target_mhz, router, place, router_patience):
        base = {"name": config.name, "variant": config.variant, "lanes": config.lanes, "memory": config.memory,
                "map_shape": list(config.map_shape), "patch_shape": list(config.patch_shape), "cycles": 1000}
        if config.variant == "window" and config.lanes == 2:
            return base | {"routed": False, "reason": "LUT4 use over 60 %", "packed": {"lut4": 1, "ff": 1, "ebr": 1, "dsp": 0},
                           "lut4_percent": 61.0}
        result = {"seed": 1, "target_mhz": target_mhz, "fmax_mhz": 50.0, "lut4": 10, "ff": 10, "ebr": 1, "dsp": 0,
                  "lut4_available": 83640, "ebr_available": 208, "seconds": 1.0}
        return base | {"routed": True, "router": router, "seconds": 1000 / 50e6, "result": result}

    monkeypatch.setattr(synth, "_build", fake_build)
    for name in ("markdown_table", "critical_path_lines", "mapper_note"):
        monkeypatch.setattr(synth, name, lambda entries: "")
    monkeypatch.setattr(figures, "gateware_commit", lambda: "c0ffee1")
    csv_path = tmp_path / "figures.csv"
    arguments = ["--out", str(tmp_path), "--lanes", "1", "2", "--on-chip", "--figures", str(csv_path)]
    assert synth.main(arguments) == 0
    assert synth.main(arguments) == 0  # a rerun over the same results records nothing new
    rows = figures.read(csv_path)
    assert [(row["variant"], row["lanes"], row["commit"]) for row in rows] == [("recursive", "1", "c0ffee1"),
                                                                               ("window", "1", "c0ffee1")]
    assert json.loads((tmp_path / "report.json").read_text())["configurations"][-1]["routed"] is False


def test_lut4_equivalent_counts_a_carry_cell_as_two():
    from lost.hdl.flow.breakdown import lut4_equivalent

    assert lut4_equivalent({"LUT4": 5, "CCU2C": 3, "TRELLIS_FF": 9}) == 11
    assert lut4_equivalent({}) == 0


@pytest.mark.fpga
def test_breakdown_counts_the_cells_of_each_component(tmp_path):
    from amaranth.hdl import Module
    from amaranth.lib import wiring
    from amaranth.lib.wiring import In, Out

    from lost.hdl.blocks import AdderTree
    from lost.hdl.flow.breakdown import cell_counts, lut4_equivalent

    class Top(wiring.Component):
        leaves: In(4 * 12)
        total: Out(14)

        def elaborate(self, platform):
            m = Module()
            m.submodules.tree = tree = AdderTree(count=4, leaf=(0, 4095), total=(0, 4 * 4095))
            m.d.comb += [tree.leaves.eq(self.leaves), self.total.eq(tree.sum)]
            return m

    counts = cell_counts(Top(), "top", tmp_path)
    # The tree is its own module: two 13-bit and one 14-bit adder in carry cells, its registers beside.
    assert lut4_equivalent(counts["top.tree"]) >= 2 * 13 + 14 and counts["top.tree"]["TRELLIS_FF"] == 2 * 13 + 14
    assert lut4_equivalent(counts["top"]) == 0
