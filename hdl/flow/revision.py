"""Elaborate one configuration of the gateware at a git revision, for :mod:`lost.hdl.flow.equiv`.

The revision's ``hdl/`` and ``model/`` are taken with ``git archive`` (or the working tree) and imported as
``lost`` in a subprocess, so the RTLIL is of that revision, not of the installed checkout.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Mapping
from pathlib import Path

from .pnr import FlowError

__all__ = ["CHECKOUT", "RevisionError", "elaborate_revision"]


class RevisionError(FlowError):
    """A revision could not be archived or elaborated."""


#: The folder holding ``hdl/`` and ``model/`` of this checkout.
CHECKOUT = Path(__file__).resolve().parents[2]

#: Run in a subprocess with the revision's ``lost`` package first on the path. The installed package is an
#: editable finder for this checkout, which would win over any path: it is removed before ``lost`` is imported.
_ELABORATE = """
import json, sys
from pathlib import Path
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
sys.path_hooks[:] = [h for h in sys.path_hooks if "editable" not in repr(h).lower()]
sys.path[:] = [p for p in sys.path if "__editable__" not in p]
sys.path_importer_cache.clear()
root, config, out = Path(sys.argv[1]), json.loads(sys.argv[2]), Path(sys.argv[3])
sys.path.insert(0, str(root))
import lost.hdl, lost.model
for package in (lost.hdl, lost.model):
    if Path(package.__file__).parent.parent != root / "lost":
        sys.exit(f"{package.__name__} was imported from {package.__file__}, not from {root}")
from amaranth.back import rtlil
sizes = dict(map_shape=tuple(config["map_shape"]), patch_shape=tuple(config["patch_shape"]),
             depth_bits=config["depth_bits"], exclusion_radius=config["exclusion_radius"])
if config["part"] == "reducer":
    from lost.hdl.interface import CorrelatorParameters
    from lost.hdl.reducer import BestFitReducer
    top = BestFitReducer(parameters=CorrelatorParameters(**sizes, lanes=config["lanes"]))
else:
    try:
        from lost.hdl.variants import build_core
    except ImportError:  # revisions before the variant table moved to lost.model: a method of the variant
        from lost.hdl.variants import variant
        def build_core(name, **options):
            return variant(name).build(**options)
    top = build_core(config["variant"], **sizes, memory=config["memory"])
# A port the component ties to a constant is not a port of the netlist (rtlil.convert refuses constants).
from amaranth.hdl import Signal, Value
ports = [value for _, _, port in top.signature.flatten(top) if isinstance(value := Value.cast(port), Signal)]
out.write_text(rtlil.convert(top, name="top", ports=ports))
"""


def _tree(revision: str | None, into: Path, checkout: Path) -> Path:
    """A folder holding ``lost/hdl`` and ``lost/model`` of ``revision`` (``None``: the working tree)."""
    package = into / "lost"
    package.mkdir(parents=True)
    if revision is None:
        source = checkout
    else:
        result = subprocess.run(["git", "-C", str(checkout), "archive", "--format=tar", revision, "hdl", "model"], capture_output=True)
        if result.returncode != 0:
            raise RevisionError(f"git archive {revision} failed: {result.stderr.decode().strip()}")
        source = into / "src"
        with tarfile.open(fileobj=io.BytesIO(result.stdout)) as archive:
            archive.extractall(source, filter="data")
    for part in ("hdl", "model"):
        (package / part).symlink_to(source / part, target_is_directory=True)
    return into


def elaborate_revision(revision: str | None, config: Mapping, out: Path, *, checkout: Path = CHECKOUT) -> str:
    """The RTLIL of one configuration of the gateware at a git revision (``None``: the working tree).

    ``config`` holds ``part`` (``"variant"`` or ``"reducer"``), ``variant``, ``memory``, ``lanes``,
    ``map_shape``, ``patch_shape``, ``depth_bits`` and ``exclusion_radius``. The revision's ``hdl/`` and
    ``model/`` are elaborated in a subprocess that imports them, not this checkout, as ``lost``.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="lost-equiv-") as tmp:
        root = _tree(revision, Path(tmp), Path(checkout))
        result = subprocess.run([sys.executable, "-c", _ELABORATE, str(root), json.dumps(dict(config)), str(out)],
                                capture_output=True, text=True, env=os.environ | {"PYTHONWARNINGS": "ignore"})
    if result.returncode != 0:
        tail = "\n".join((result.stderr or result.stdout).splitlines()[-15:])
        raise RevisionError(f"elaborating {revision or 'the working tree'} failed:\n{tail}")
    return out.read_text()
