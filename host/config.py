"""Settings with strict types, units and ranges: every scenario table and the navigation parameters.

LOST's settings are frozen dataclasses (``lost.host.scenario``'s tables, ``lost.host.nav.NavParameters``, the tracker's and the
USBL's); each package builds its own from here (``lost.host.nav.navigation_parameters``), so this module imports none of them.
They stay plain dataclasses; this module validates what comes in from files and the command line
*before* one is built, with pydantic v2 in strict mode (a model generated from the dataclass's own
fields and type hints, so a new field is validated the moment it is declared):

- strict types: ``"false"`` is no boolean, ``"False"`` no ``mean_compensation``, ``10.5`` no row
  count, a string no number; an integer is a float (TOML writes ``600`` for ``600.0``); NaN and
  infinities are refused;
- ranges: a field's type may carry pydantic constraints, e.g. ``speed_kn: PositiveFloat``
  (``Annotated[float, Field(gt=0)]``), as the scenario tables' do; the navigation parameters keep
  their ranges in ``NavParameters.__post_init__`` (one place), whose message is prefixed with where
  the value came from;
- unknown fields are errors, so a typo never falls back to a default;
- errors name the field's path and its unit, on one line: ``sensors.sonar.noise (metres): Input
  should be greater than or equal to 0, got -1``.

Why pydantic: it is the well-kept, widely used validation library of Python (pydantic-core in
Rust), validates stdlib type hints, ``Annotated`` constraints and unions in strict mode as they are
written, and reports every failure with its location, which is what a path-naming message needs.
"""

from __future__ import annotations

import dataclasses
import functools
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

__all__ = [
    "ConfigError", "validate_fields", "build", "read_toml", "read_navigation_table",
    "PositiveFloat", "NonNegativeFloat", "PositiveInt", "NonNegativeInt", "Fraction", "FiniteFloat",
]

#: Strict types, no unknown field, no NaN or infinity.
STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False, arbitrary_types_allowed=True)

PositiveFloat = Annotated[float, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]
PositiveInt = Annotated[int, Field(gt=0)]
NonNegativeInt = Annotated[int, Field(ge=0)]
Fraction = Annotated[float, Field(ge=0, le=1)]
FiniteFloat = float  # strict mode already refuses NaN and infinities (allow_inf_nan=False)

# Unit of a field, from the ending of its name: the house names every quantity with its unit.
_UNITS = (("_mps2", "m/s^2"), ("_mps", "m/s"), ("_m_s2", "m/s^2"), ("_m_s", "m/s"),  # lost.host.usbl writes m/s as _m_s
          ("_per_s", "1/s"), ("_dps", "degrees/s"), ("_deg", "degrees"), ("_kn", "knots"),
          ("_hz", "hertz"), ("_m", "metres"), ("_s", "seconds"))


class ConfigError(ValueError):
    """A setting of the wrong type, out of range or unknown; the message names its path (and unit)."""


def unit_of(name: str, annotation: Any = float) -> str | None:
    """The unit a field's name declares (``out_m`` -> metres), or None; a count has none (the tracker's M of M-of-N, ``confirm_m``)."""
    if annotation is int:
        return None
    return next((unit for suffix, unit in _UNITS if name.endswith(suffix)), None)


@functools.cache
def _schema(cls: type, constraints: tuple[tuple[str, Any], ...]) -> type[BaseModel]:
    hints = typing.get_type_hints(cls, include_extras=True)
    extra = dict(constraints)
    specs = {}
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        hint = hints[f.name]
        if f.name in extra:
            hint = _constrained(hint, extra[f.name])
        default = f.default if f.default is not dataclasses.MISSING else (
            Field(default_factory=f.default_factory) if f.default_factory is not dataclasses.MISSING else ...)
        specs[f.name] = (hint, default)
    return create_model(f"{cls.__name__}Settings", __config__=STRICT, **specs)


def _constrained(hint: Any, constraint: Any) -> Any:
    """``float | None`` with a range: the range on the float, None still allowed."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and type(None) in args:
        inner = [a for a in args if a is not type(None)]
        return Annotated[inner[0], constraint] | None if len(inner) == 1 else hint
    return Annotated[hint, constraint]


def _tuples(value: Any) -> Any:
    """TOML and ``--set`` give arrays as lists; the settings' sequences are tuples (strict mode tells them apart)."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def validate_fields(cls: type, table: Any, where: str, constraints: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Validate ``table`` against the fields of dataclass ``cls``; return the given fields' validated values.

    Parameters
    ----------
    cls : dataclass type
        Its fields' type hints (``Annotated`` constraints included) are the schema.
    table : mapping
        The values, as read from TOML or the command line.
    where : str
        The table's path for messages (``"sensors.sonar"``; ``""`` for the top level).
    constraints : mapping of field name to ``pydantic.Field``, optional
        Ranges for fields whose class cannot carry them.

    Raises
    ------
    ConfigError
        ``table`` is no table, or a field is unknown, of the wrong type or out of range: one line
        naming every failing field's path (and unit).
    """
    if not isinstance(table, Mapping):
        raise ConfigError(f"[{where}] must be a table of settings, got {table!r}")
    known = sorted(f.name for f in dataclasses.fields(cls) if f.init)
    unknown = sorted(set(table) - set(known))
    if unknown:
        raise ConfigError(f"[{where or 'top level'}] has unknown field(s) {unknown}; known fields are {known}")
    schema = _schema(cls, tuple(sorted((constraints or {}).items(), key=lambda item: item[0])))
    data = {key: _tuples(value) for key, value in table.items()}
    try:
        validated = schema.model_validate(data)
    except ValidationError as error:
        hints = typing.get_type_hints(cls)
        raise ConfigError("; ".join(_describe(problem, where, hints) for problem in error.errors())) from None
    return {key: getattr(validated, key) for key in data}


def _describe(problem: Mapping[str, Any], where: str, hints: Mapping[str, Any]) -> str:
    loc = [str(part) for part in problem["loc"]]
    field = loc[0] if loc else ""
    path = ".".join([where, *loc] if where else loc)
    unit = unit_of(field, hints.get(field, float))
    message = problem["msg"]
    got = problem.get("input")
    shown = f"{got!r} ({type(got).__name__})" if isinstance(got, str | bool) or got is None else repr(got)
    return f"{path}{f' ({unit})' if unit else ''}: {message}, got {shown}"


def build(cls: type, table: Any, where: str) -> Any:
    """A table of a settings file as ``cls``, its values checked first by the strict schema of ``cls``'s type hints."""
    return cls(**validate_fields(cls, table, where))


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """The tables of a TOML file; ``FileNotFoundError`` names ``what`` was looked for, bad TOML is a ``ConfigError``."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"no {what} at {path}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ConfigError(f"{path} is not valid TOML: {error}") from None


def read_navigation_table(path: str | Path) -> dict[str, Any]:
    """The ``[navigation]`` table of a TOML file (a scenario, or a file holding only that table).

    Raises
    ------
    ConfigError
        The file is missing, not TOML, or has no ``[navigation]`` table (named).
    """
    path = Path(path)
    try:
        data = read_toml(path, "configuration file")
    except FileNotFoundError as error:
        raise ConfigError(str(error)) from None
    table = data.get("navigation")
    if table is None:
        raise ConfigError(f"{path} has no [navigation] table (it has: {', '.join(data) or 'nothing'})")
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: navigation must be a table, got {table!r}")
    return table

