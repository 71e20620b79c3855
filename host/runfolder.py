"""Run folders that are never half-written: a run is written aside, then renamed into place whole.

:func:`run_folder` is a context manager around everything a run writes::

    with run_folder(Path("runs/demo"), replace=args.replace) as folder:
        ...                      # write track.csv, summary.json, plots into `folder`
    # here runs/demo holds exactly the new run

- Before any work it checks that ``out`` can be written: its parent is created (or must be a
  folder), a temporary folder ``.NAME.partial-XXXX`` is made beside ``out`` (so the final rename
  stays on one file system) and a few megabytes must be free there.
- Every run carries a marker, ``lost-run.json`` (the command that wrote it and when), written as the
  run is installed; a folder holds a LOST run when it has that marker. Such a folder is refused unless
  ``replace=True``; then it is replaced whole, never merged, so no file of the earlier run survives
  beside the new one. A non-empty folder without the marker is refused even with ``replace`` (another
  tool's ``summary.json`` does not make it ours to delete), and so is a symbolic link, and an earlier
  run that cannot be moved (read-only): all before any work is done.
- A lock (``fcntl.flock`` on ``.NAME.lock`` beside ``out``) refuses a second run on the same folder
  while the first is writing; the kernel releases it when the process dies, so a killed run leaves
  no stale lock.
- An exception inside the block (an error, a failed write, Ctrl-C) deletes the temporary folder
  and leaves ``out`` exactly as it was; :class:`RunFolderError`'s messages and
  :func:`describe_untouched` say so.

The replacement is two renames (old run aside, new run in): between them, for microseconds, ``out``
does not exist; were the machine to stop there, the previous run is still whole in
``.NAME.old-XXXX/run``, and the next run on ``out`` puts it back before anything else. A run killed
outright (SIGKILL) leaves its ``.NAME.partial-XXXX``; the next run on ``out`` deletes it.

A run that writes as it goes (``lost serve``'s log: what it has already served) names those files in
``keep``: a partial folder holding one of them is never deleted. An exception inside the block moves it
to ``NAME.stopped-YYYYmmddTHHMMSSZ`` beside ``out``; the next run on ``out`` moves a killed run's so,
instead of deleting it. Either says where it went (a warning).
"""

from __future__ import annotations

import contextlib
import fcntl
import glob
import json
import math
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable, Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RunFolderError", "run_folder", "holds_a_run", "describe_untouched", "write_summary", "atomic_write", "folder_lock", "writable_parent", "RUN_MARKER",
           "MIN_FREE_BYTES"]

#: The file that marks a folder as a LOST run (:func:`run_folder` writes it into every run).
RUN_MARKER = "lost-run.json"

#: Inside a partial folder: the files of a run that writes as it goes, kept when the run does not finish.
KEEP_MARKER = ".lost-keep"

#: A run's files (track CSV, summary, plots) take a few MB; refuse to start with less free.
MIN_FREE_BYTES = 16 * 1024 * 1024


class RunFolderError(OSError):
    """The output folder cannot take this run (not writable, another run there, locked)."""


def holds_a_run(folder: Path) -> bool:
    """Whether ``folder`` holds a finished LOST run: its marker is there and reads as ours."""
    try:
        return json.loads((folder / RUN_MARKER).read_text(encoding="utf-8")).get("lost_run") == 1
    except (OSError, ValueError, AttributeError):
        return False


def atomic_write(path: Path, write: Callable[[Any], object]) -> Path:
    """Call ``write(handle)`` on a temporary file beside ``path``, then move it onto ``path``."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".partial")
    try:
        with os.fdopen(fd, "w", newline="") as handle:
            write(handle)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; the result is an ordinary file
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_summary(path: Path, summary: Mapping[str, Any]) -> Path:
    """``summary.json`` of a run: NaN and infinities written as null, NumPy scalars and arrays as JSON values."""
    def clean(value: Any) -> Any:
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if isinstance(value, np.generic):
            value = value.item()
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if isinstance(value, Mapping):
            return {str(k): clean(v) for k, v in value.items()}
        if isinstance(value, list | tuple):
            return [clean(v) for v in value]
        return value

    path.write_text(json.dumps(clean(summary), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path


def describe_untouched(out: Path) -> str:
    """One sentence saying what an interrupted run left in ``out``."""
    if holds_a_run(out):
        return f"the previous run in {out} is intact"
    return f"nothing was written to {out}"


def _check_target(out: Path, replace: bool) -> None:
    if out.is_symlink():
        raise RunFolderError(f"--out {out} is a symbolic link (to {os.readlink(out)}); give the folder itself, a run replaces its folder whole")
    if out.exists() and not out.is_dir():
        raise RunFolderError(f"--out {out} is a file, not a folder")
    if not out.is_dir() or not any(out.iterdir()):
        return
    if not holds_a_run(out):
        raise RunFolderError(
            f"--out {out} is a non-empty folder that holds no LOST run (no {RUN_MARKER}); choose an empty or new folder "
            "(--replace only replaces an earlier run)"
        )
    if not replace:
        raise RunFolderError(f"--out {out} already holds a run; pass --replace to replace it whole, or choose another folder")
    if not os.access(out, os.W_OK | os.X_OK):
        raise RunFolderError(f"--out {out} holds a run that cannot be replaced: the folder is read-only")


def writable_parent(out: Path) -> Path:
    parent = out.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise RunFolderError(f"cannot create {out}: {parent} exists and is not a folder") from None
    except OSError as error:
        raise RunFolderError(f"cannot create the folder {parent} for {out}: {error.strerror or error}") from None
    if not os.access(parent, os.W_OK | os.X_OK):
        raise RunFolderError(f"cannot write {out}: the folder {parent} is not writable")
    free = shutil.disk_usage(parent).free
    if free < MIN_FREE_BYTES:
        raise RunFolderError(f"cannot write {out}: only {free // 1024} kB free on its file system, a run needs {MIN_FREE_BYTES // 2**20} MB")
    return parent


@contextlib.contextmanager
def folder_lock(parent: Path, out: Path) -> Iterator[None]:
    path = parent / f".{out.name}.lock"
    while True:
        handle = open(path, "a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            handle.close()
            raise RunFolderError(f"another lost run (pid {holder}) is writing to {out}; wait for it or choose another --out") from None
        # The holder before us may have unlinked the file between our open and our lock: lock the live one.
        try:
            same = os.path.samestat(os.fstat(handle.fileno()), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        handle.close()
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        handle.close()


def _recover(parent: Path, out: Path) -> None:
    """Clear what a killed run left beside ``out`` (we hold its lock, so nobody else is using it).

    A partial run is deleted. A previous run set aside for a replacement is put back when the
    machine stopped between the two renames (``out`` missing), else deleted.
    """
    name = glob.escape(out.name)  # a folder named run[1] is no pattern
    for partial in parent.glob(f".{name}.partial-*"):
        if not _set_aside_if_kept(partial, out, "killed"):
            shutil.rmtree(partial, ignore_errors=True)
    for old in parent.glob(f".{name}.old-*"):
        if not out.exists() and (old / "run").is_dir():
            os.replace(old / "run", out)
        shutil.rmtree(old, ignore_errors=True)


def _set_aside_if_kept(partial: Path, out: Path, how: str) -> bool:
    """Move a partial run that holds a kept file to ``NAME.stopped-TIME`` beside ``out``; whether it did."""
    marker = partial / KEEP_MARKER
    kept = marker.read_text(encoding="utf-8").split() if marker.is_file() else []
    if not any((partial / name).is_file() and (partial / name).stat().st_size > 0 for name in kept):
        return False
    stamp = datetime.fromtimestamp(marker.stat().st_mtime, UTC).strftime("%Y%m%dT%H%M%SZ")
    target = out.with_name(f"{out.name}.stopped-{stamp}")
    for n in range(1, 1000):
        if not target.exists():
            break
        target = out.with_name(f"{out.name}.stopped-{stamp}-{n}")
    try:
        os.replace(partial, target)
    except OSError as error:
        warnings.warn(f"a {how} run's {', '.join(kept)} stay in {partial} (moving it to {target} failed: {error.strerror or error})",
                      stacklevel=3)
        return True
    warnings.warn(f"a {how} run's {', '.join(kept)} kept in {target}", stacklevel=3)
    return True


def _install(partial: Path, out: Path, parent: Path) -> None:
    """Move the finished run into place, replacing (whole) an earlier run or an empty folder."""
    if out.is_dir() and any(out.iterdir()):
        old = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out.name}.old-"))
        try:
            os.replace(out, old / "run")
        except OSError as error:
            old.rmdir()
            raise RunFolderError(f"cannot replace the run in {out}: {error.strerror or error}; it is left as it was") from None
        os.replace(partial, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(partial, out)  # POSIX rename replaces an empty folder


def _mark(folder: Path, command: str) -> None:
    marker = {"lost_run": 1, "command": command, "finished": datetime.now(UTC).isoformat(timespec="seconds")}
    (folder / RUN_MARKER).write_text(json.dumps(marker) + "\n", encoding="utf-8")


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def run_folder(out: str | os.PathLike, *, replace: bool = False, command: str = "run", keep: tuple[str, ...] = ()) -> Iterator[Path]:
    """Yield a fresh temporary folder for a run's files; on success it becomes ``out``, whole.

    Parameters
    ----------
    out : path-like
        The run's folder.
    replace : bool
        Replace an earlier run in ``out`` (whole). Without it such a folder is refused.
    command : str
        The subcommand writing the run, recorded in its marker.
    keep : tuple of str
        Files the run writes as it goes, kept (with their folder) when the run fails or is killed.

    Yields
    ------
    Path
        The folder to write into (beside ``out``, on the same file system).

    Raises
    ------
    RunFolderError
        ``out`` is a file, a non-empty folder that is no run, an earlier run without ``replace``,
        locked by another run, or its parent is not writable or nearly full. Raised before the
        block runs, so no work is wasted.
    """
    out = Path(out).absolute()
    _check_target(out, replace)
    parent = writable_parent(out)
    with folder_lock(parent, out):
        _recover(parent, out)
        _check_target(out, replace)  # again, now that no other run can be installing one
        try:
            partial = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out.name}.partial-"))
        except OSError as error:
            raise RunFolderError(f"cannot write {out}: making a folder in {parent} failed ({error.strerror or error})") from None
        partial.chmod(0o777 & ~_umask())  # mkdtemp makes it private; a run folder is an ordinary folder
        if keep:
            (partial / KEEP_MARKER).write_text(" ".join(keep) + "\n", encoding="utf-8")
        installed = False
        try:
            yield partial
            _mark(partial, command)
            _install(partial, out, parent)
            installed = True
            (out / KEEP_MARKER).unlink(missing_ok=True)
        finally:
            if installed or not _set_aside_if_kept(partial, out, "stopped"):
                shutil.rmtree(partial, ignore_errors=True)
