"""Validated parameter sets: one declaration per set, clear errors, presets and TOML files.

Each parameter set is declared once, as a frozen dataclass whose fields are annotated
``Annotated[float, positive("joint inertia I_j [kg m^2]")]`` (bounds and a description
ending in the unit in brackets).  :func:`schema_of` derives the pydantic schema (used for
TOML files and by the dataclass's own ``__post_init__`` through :func:`check`) from those
annotations, so the two can never drift.  Errors read
``invalid joint_inertia = -1.0: must be > 0 and finite [kg m^2]``.
"""

from __future__ import annotations

import tomllib
import typing
from collections.abc import Callable, Mapping
from dataclasses import MISSING, asdict, fields
from functools import cache
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from seactl.base.outputs import note_input
from seactl.errors import InputError

_BOUNDS = (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))


def positive(description: str, **bounds: Any) -> Any:
    """Field metadata: a finite value > 0 (``bounds`` may add ``le`` etc.)."""
    return Field(description=description, gt=0, allow_inf_nan=False, **bounds)


def nonnegative(description: str, **bounds: Any) -> Any:
    """Field metadata: a finite value >= 0."""
    return Field(description=description, ge=0, allow_inf_nan=False, **bounds)


@cache
def schema_of(cls: type) -> type[BaseModel]:
    """The pydantic model of a dataclass whose fields are ``Annotated[type, Field(...)]``:
    same names, bounds, descriptions and defaults; unknown keys are refused."""
    hints = typing.get_type_hints(cls, include_extras=True)
    spec = {f.name: (hints[f.name], ... if f.default is MISSING else f.default)
            for f in fields(cls)}
    return create_model(f"{cls.__name__}Schema", __config__=ConfigDict(extra="forbid"),
                        **spec)


def check(obj: Any) -> None:
    """Validate a dataclass instance against :func:`schema_of` its class (InputError)."""
    check_values(type(obj), asdict(obj))


def check_values(cls: type, values: Mapping[str, Any]) -> None:
    """Validate field values of the dataclass ``cls`` (InputError naming the field)."""
    validate(schema_of(cls), values)


def input_error(exc: ValidationError, model: type[BaseModel], prefix: str = "") -> InputError:
    """The first pydantic error as an :class:`InputError` naming field, value and range."""
    err = exc.errors()[0]
    field = prefix + ".".join(str(p) for p in err["loc"])
    if err["type"] == "extra_forbidden":
        known = ", ".join(model.model_fields)
        return InputError(field, err.get("input"), f"one of the known keys ({known})")
    if err["type"] == "missing":
        return InputError(field, None, "given (required field)")
    info = model.model_fields.get(str(err["loc"][0]))
    bounds = []
    if info is not None:
        for meta in info.metadata:
            bounds += [f"{sym} {getattr(meta, attr)}" for attr, sym in _BOUNDS
                       if getattr(meta, attr, None) is not None]
    valid = (" and ".join(bounds) + " and finite") if bounds else err["msg"].lower()
    desc = (info.description or "") if info is not None else ""
    if desc.endswith("]") and "[" in desc:
        valid += " " + desc[desc.rindex("["):]
    return InputError(field, err.get("input"), valid)


def validate(model: type[BaseModel], data: Mapping[str, Any]) -> BaseModel:
    """``model.model_validate(data)`` raising :class:`InputError` instead."""
    try:
        return model.model_validate(dict(data))
    except ValidationError as exc:
        raise input_error(exc, model) from None


def read_toml(field: str, spec: str, what: str) -> dict[str, Any]:
    """Read a user's TOML file (``field`` names the option for error messages)."""
    path = Path(spec)
    if path.suffix != ".toml" or not path.is_file():
        raise InputError(field, spec, f"{what} or an existing .toml file")
    note_input(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(field, spec, f"valid TOML ({exc})") from None
    except UnicodeDecodeError:
        raise InputError(field, spec, "a UTF-8 text file (TOML); this file is binary") from None
    except OSError as exc:
        raise InputError(field, spec, f"a readable file ({exc.strerror or exc})") from None


def load_params(spec: str | Path, presets: Mapping[str, Any], cls: Callable[..., Any],
                field: str = "actuator") -> Any:
    """A preset by name, or a TOML file whose top level (or single ``[actuator]`` table)
    holds the fields of the dataclass ``cls``, validated by :func:`schema_of` ``cls``."""
    key = str(spec)
    if key.lower() in presets:
        return presets[key.lower()]
    data = read_toml(field, key, f"a preset ({', '.join(presets)})")
    if "actuator" in data and isinstance(data["actuator"], dict) and len(data) == 1:
        data = data["actuator"]
    data.setdefault("name", Path(key).stem)
    obj = validate(schema_of(cls), data)
    return cls(**{f.name: getattr(obj, f.name) for f in fields(cls)})
