"""Files shipped inside the package (scenarios, casts): their names and paths, one way for every system."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["shipped_names", "shipped_path"]


def shipped_names(package: str, folder: str = "scenarios", suffix: str = ".toml") -> list[str]:
    """Names (without ``suffix``) of the files in ``package``'s ``folder``."""
    return sorted(p.name.removesuffix(suffix) for p in (resources.files(package) / folder).iterdir() if p.name.endswith(suffix))


def shipped_path(package: str, name: str, *, what: str, folder: str = "scenarios", suffix: str = ".toml") -> Path:
    """Path of the shipped file ``name``; a ValueError naming ``what`` and listing the shipped ones otherwise."""
    path = Path(str(resources.files(package) / folder / f"{name}{suffix}"))
    if not path.is_file():
        raise ValueError(f"no built-in {what} {name!r}; the shipped ones are {shipped_names(package, folder, suffix)}")
    return path
