"""A loop file's schema: its tables, block kinds and size limits."""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from seactl.base.limits import (
    MAX_LOOP_BLOCKS,
    MAX_LOOP_FILE_BYTES,
    MAX_LOOP_ORDER,
    MAX_LOOP_SIGNALS,
    MAX_NESTING,
    RANGES,
    derive_seconds,
    human_bytes,
    human_seconds,
)
from seactl.base.outputs import note_input
from seactl.errors import InputError, LoopFileError


# ------------------------------------------------------------------ block kinds
@dataclass(frozen=True)
class Kind:
    """A block kind: role, parameters (name -> (default or None if required, check)) and
    its transfer ``tf(values) -> (num, den)`` (coefficients highest power first)."""

    role: str
    params: dict[str, tuple[Any, str]]
    tf: Callable[[dict[str, Any]], tuple[list[Any], list[Any]]]
    doc: str
    derivative: bool = False  # numerator one degree above the denominator allowed


def _tc(f_hz: Any) -> Any:
    """Time constant 1/(2 pi f) [s]; inf -> 0 (no filter)."""
    return np.where(np.isinf(f_hz), 0.0, 1.0 / (2 * np.pi * np.asarray(f_hz, float)))


def _pid(v: dict[str, Any]) -> tuple[list[Any], list[Any]]:
    tf = _tc(v["filter_hz"])
    return ([v["kp"] * tf + v["kd"], v["kp"] + v["ki"] * tf, v["ki"]], [tf, 1.0, 0.0])


def _w(v: dict[str, Any], key: str = "f_hz") -> Any:
    return 2 * np.pi * v[key]


_R, GT0, GE0, ANY = "required", "> 0", ">= 0", "any"
KINDS: dict[str, Kind] = {
    # physics (role plant)
    "inertia": Kind("plant", {"inertia": (None, GT0), "damping": (0.0, GE0)},
                    lambda v: ([1.0], [v["inertia"], v["damping"], 0.0]),
                    "position = torque / (inertia s^2 + damping s)"),
    "load": Kind("plant", {"inertia": (None, GT0), "damping": (0.0, GE0), "stiffness": (0.0, GE0)},
                 lambda v: ([1.0], [v["inertia"], v["damping"], v["stiffness"]]),
                 "position = torque / (inertia s^2 + damping s + stiffness)"),
    "spring": Kind("plant", {"stiffness": (None, GT0)}, lambda v: ([v["stiffness"]], [1.0]),
                   "torque = stiffness * deflection"),
    "damper": Kind("plant", {"damping": (None, GE0)}, lambda v: ([v["damping"], 0.0], [0.0, 1.0]),
                   "torque = damping * s * deflection", derivative=True),
    "plant_tf": Kind("plant", {"num": (None, "list"), "den": (None, "list")},
                     lambda v: (list(v["num"]), list(v["den"])), "num(s) / den(s), proper"),
    "current_to_torque": Kind("plant", {"constant": (None, GT0)},
                              lambda v: ([v["constant"]], [1.0]), "torque = constant * current"),
    # controllers (role controller) and sensors
    "gain": Kind("controller", {"gain": (None, ANY)}, lambda v: ([v["gain"]], [1.0]), "gain"),
    "sum": Kind("controller", {}, lambda v: ([1.0], [1.0]), "sum of the signed inputs"),
    "delay": Kind("controller", {}, lambda v: ([1.0], [1.0]), "pure delay (delay_ms)"),
    "sensor": Kind("sensor", {"gain": (1.0, ANY)}, lambda v: ([v["gain"]], [1.0]),
                   "measurement of a plant signal"),
    "pd": Kind("controller", {"kp": (0.0, ANY), "kd": (0.0, ANY), "filter_hz": (math.inf, GT0)},
               lambda v: ([v["kp"] * _tc(v["filter_hz"]) + v["kd"], v["kp"]],
                          [_tc(v["filter_hz"]), 1.0]),
               "kp + kd s / (s/(2 pi filter_hz) + 1)", derivative=True),
    "pid": Kind("controller", {"kp": (0.0, ANY), "ki": (0.0, ANY), "kd": (0.0, ANY),
                               "filter_hz": (math.inf, GT0)}, _pid,
                "kp + ki/s + kd s / (s/(2 pi filter_hz) + 1)", derivative=True),
    "lowpass1": Kind("controller", {"f_hz": (None, GT0), "gain": (1.0, ANY)},
                     lambda v: ([v["gain"]], [1.0 / _w(v), 1.0]), "gain / (s/(2 pi f_hz) + 1)"),
    "lowpass2": Kind("controller", {"f_hz": (None, GT0), "zeta": (math.sqrt(0.5), GT0),
                                    "gain": (1.0, ANY)},
                     lambda v: ([v["gain"] * _w(v) ** 2], [1.0, 2 * v["zeta"] * _w(v),
                                                           _w(v) ** 2]),
                     "gain w^2 / (s^2 + 2 zeta w s + w^2), w = 2 pi f_hz"),
    "notch": Kind("controller", {"f_hz": (None, GT0), "zeta_num": (0.0, GE0),
                                 "zeta_den": (0.5, GT0)},
                  lambda v: ([1.0, 2 * v["zeta_num"] * _w(v), _w(v) ** 2],
                             [1.0, 2 * v["zeta_den"] * _w(v), _w(v) ** 2]),
                  "(s^2 + 2 zeta_num w s + w^2) / (s^2 + 2 zeta_den w s + w^2)"),
    "leadlag": Kind("controller", {"gain": (1.0, ANY), "zero_hz": (None, GT0),
                                   "pole_hz": (None, GT0)},
                    lambda v: ([v["gain"] / _w(v, "zero_hz"), v["gain"]],
                               [1.0 / _w(v, "pole_hz"), 1.0]),
                    "gain (s/(2 pi zero_hz) + 1) / (s/(2 pi pole_hz) + 1)"),
    "tf": Kind("controller", {"num": (None, "list"), "den": (None, "list")},
               lambda v: (list(v["num"]), list(v["den"])), "num(s) / den(s), proper"),
    "dob": Kind("controller", {"nominal_num": (None, "list"), "nominal_den": (None, "list"),
                               "q_hz": (None, GT0), "q_order": (2, "int")},
                lambda v: ([1.0], [1.0]),
                "u = input - Q (Pn^-1 measurement - u), Q = 1/(s/(2 pi q_hz) + 1)^q_order"),
}
"""The block library (docs/loops.md lists each kind's fields)."""

COMMON_BLOCK_KEYS = {"name", "kind", "input", "output", "process", "delay_ms", "delay_s",
                     "measurement", "description"}


# ------------------------------------------------------------------ file schema
class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ProcessModel(_Model):
    rate_hz: float = Field(1000.0, gt=0, allow_inf_nan=False, description="rate [Hz]")
    latency_ms: float | str | None = Field(None, description="latency of a block with "
                                           "delay = 'process' [ms]: number or expression")
    latency_s: float | str | None = Field(None, description="the same in seconds (give "
                                          "one of the two; neither: 0)")


class BreakModel(_Model):
    name: str
    signal: str
    description: str = ""


class PortModel(_Model):
    name: str
    position: str
    force: str
    sign: float = Field(-1.0, description="Z = sign * force / (s position)")


class SignalsModel(_Model):
    inputs: list[str] = []
    reference: str | None = None
    disturbance: str | None = None
    output: str | None = None
    reference_step: float | None = Field(None, allow_inf_nan=False, description="the "
                                         "default step of the reference (its unit)")
    reference_unit: str | None = Field(None, max_length=40, description="the unit of the "
                                       "reference, e.g. rad or m")

    @field_validator("reference_step")
    @classmethod
    def _nonzero_step(cls, v: float | None) -> float | None:
        if v is not None and v == 0:
            raise ValueError("a non-zero step")
        return v


class AnalysisModel(_Model):
    f_min_hz: float | None = Field(None, ge=RANGES["freq_hz"][0], le=RANGES["freq_hz"][1],
                                   allow_inf_nan=False)
    f_max_hz: float | None = Field(None, ge=RANGES["freq_hz"][0], le=RANGES["freq_hz"][1],
                                   allow_inf_nan=False)


class BlockModel(BaseModel):
    model_config = ConfigDict(extra="allow")

    name: str
    kind: str
    input: str | list[str]
    output: str
    process: str | None = None
    delay_ms: float | str | None = None
    delay_s: float | str | None = None
    measurement: str | None = None
    description: str = ""


class LoopFileModel(_Model):
    name: str = "loop"
    description: str = ""
    default_process: str | None = None
    variables: dict[str, float] = {}
    parameters: dict[str, float | str] = {}
    processes: dict[str, ProcessModel] = {}
    blocks: list[BlockModel] = Field(min_length=1)
    breaks: list[BreakModel] = []
    ports: list[PortModel] = []
    signals: SignalsModel = SignalsModel()
    analysis: AnalysisModel = AnalysisModel()


def validation_error(exc: ValidationError, file: str, data: Mapping[str, Any]) -> LoopFileError:
    """The first pydantic error as a :class:`LoopFileError` naming block and field."""
    err = exc.errors()[0]
    loc = list(err["loc"])
    where = ".".join(str(p) for p in loc)
    if len(loc) >= 2 and loc[0] in ("blocks", "breaks", "ports") and isinstance(loc[1], int):
        items = data.get(loc[0]) or []
        item = items[loc[1]] if loc[1] < len(items) and isinstance(items[loc[1]], dict) else {}
        label = f"{loc[0][:-1]} {item.get('name', '#' + str(loc[1] + 1))!r}"
        where = label + (f", field {'.'.join(str(p) for p in loc[2:])!r}" if loc[2:] else "")
    elif loc and loc[0] == "variables" and len(loc) > 1:
        where = f"variable {loc[1]!r}"
    if err["type"] == "missing":
        return LoopFileError(file, where, None, "required field missing")
    if err["type"] == "extra_forbidden":
        return LoopFileError(file, where, err.get("input"), "unknown key")
    if loc and loc[0] == "variables":
        return LoopFileError(file, where, err.get("input"),
                             "a number (expressions go under [parameters])")
    return LoopFileError(file, where, err.get("input"), err["msg"].lower())


def known_keys(model: type[BaseModel], loc: Sequence[Any]) -> str:
    """The keys valid where an unknown key was found (for the error message)."""
    fields = model.model_fields
    for part in loc[:-1]:
        info = fields.get(str(part)) if isinstance(part, str) else None
        ann = getattr(info, "annotation", None) if info is not None else None
        sub = next((a for a in getattr(ann, "__args__", (ann,)) if isinstance(a, type)
                    and issubclass(a, BaseModel)), None)
        if sub is None:
            continue
        fields = sub.model_fields
    return ", ".join(fields)


# ------------------------------------------------------------------ size
_TOML_STRINGS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:\\.|[^"\\\n])*"'
                           r"|'[^'\n]*'|#[^\n]*")
_TOML_KEY = re.compile(r"^\s*([^=\s\[\]{}][^=\n]*?)\s*=", re.M)


def check_toml_nesting(text: str, file: str) -> None:
    """Refuse TOML text whose arrays or inline tables nest deeper than
    :data:`~seactl.base.limits.MAX_NESTING` (before parsing it: the parser recurses), naming
    the key where it happens."""
    bare = _TOML_STRINGS.sub(lambda m: "\n" * m.group().count("\n") or "s", text)
    depth, key, table = 0, "", ""
    for lineno, line in enumerate(bare.splitlines(), 1):
        if depth == 0:
            head = line.strip()
            if head.startswith("["):
                table = head.strip("[] ")
                continue
            m = _TOML_KEY.match(line)
            key = (f"{table}." if table else "") + (m.group(1).strip() if m else "")
        for ch in line:
            depth += 1 if ch in "[{" else -1 if ch in "]}" else 0
            if depth > MAX_NESTING:
                raise LoopFileError(file, f"key {key!r} (line {lineno})", None,
                                    f"arrays and tables nested at most {MAX_NESTING} deep")
        depth = max(depth, 0)


def read_toml_file(path: Any, what: str) -> dict[str, Any]:
    """The table of a TOML file (a loop file, a delay-equation file), refused with
    :class:`~seactl.errors.LoopFileError` when it is missing, larger than
    :data:`~seactl.base.limits.MAX_LOOP_FILE_BYTES`, nested too deep or not valid TOML.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file is, for the messages (``"loop file"``).

    Returns
    -------
    dict
        The parsed table.
    """
    if not isinstance(path, (str, Path)):
        raise InputError("path", type(path).__name__, f"a path to a .toml {what}")
    p = Path(path)
    if not p.is_file():
        raise LoopFileError(str(path), "file", None, f"an existing .toml {what}")
    note_input(p)
    try:
        size = p.stat().st_size
        if size > MAX_LOOP_FILE_BYTES:
            raise LoopFileError(str(path), "file", None, f"a {what} of at most "
                                f"{human_bytes(MAX_LOOP_FILE_BYTES)} (this one has "
                                f"{human_bytes(size)})")
        text = p.read_text()
        check_toml_nesting(text, str(path))
        return tomllib.loads(text)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise LoopFileError(str(path), "file", None, f"valid TOML ({exc})") from None
    except RecursionError:
        raise LoopFileError(str(path), "file", None, f"arrays and tables nested at most "
                            f"{MAX_NESTING} deep") from None
    except OSError as exc:
        raise LoopFileError(str(path), "file", None, f"a readable file ({exc.strerror})"
                            ) from None


def check_nesting(data: Any, file: str) -> None:
    """Refuse loop tables (as parsed, or collected by a builder) nested deeper than
    :data:`~seactl.base.limits.MAX_NESTING`, naming the path (iterative: no recursion)."""
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        node, path, d = stack.pop()
        if d > MAX_NESTING:
            shown = path if len(path) <= 60 else path[:57] + "..."
            raise LoopFileError(file, f"key {shown!r}", None,
                                f"arrays and tables nested at most {MAX_NESTING} deep")
        if isinstance(node, Mapping):
            stack.extend((v, f"{path}.{k}" if path else str(k), d + 1) for k, v in node.items())
        elif isinstance(node, (list, tuple)):
            stack.extend((v, f"{path}[{i}]", d + 1) for i, v in enumerate(node))


def check_size(file: str, n_blocks: int, n_signals: int = 0, order: int = 0) -> None:
    """Refuse a loop larger than :mod:`seactl.base.limits` allows, with the estimate: more
    blocks or signals than :data:`~seactl.base.limits.MAX_LOOP_BLOCKS` /
    :data:`~seactl.base.limits.MAX_LOOP_SIGNALS` (the symbolic derivation grows as the cube
    of the signals) or an order above :data:`~seactl.base.limits.MAX_LOOP_ORDER`."""
    if n_blocks > MAX_LOOP_BLOCKS or n_signals > MAX_LOOP_SIGNALS:
        what, n, lim = (("blocks", n_blocks, MAX_LOOP_BLOCKS) if n_blocks > MAX_LOOP_BLOCKS
                        else ("signals", n_signals, MAX_LOOP_SIGNALS))
        n_sig = max(n_signals, n_blocks)
        raise LoopFileError(file, "[[blocks]]", None, f"at most {lim} {what} (this loop has "
                            f"{n}: deriving its transfers would take about "
                            f"{human_seconds(derive_seconds(n_sig))} or more, growing as the "
                            "cube of its signals)")
    if order > MAX_LOOP_ORDER:
        raise LoopFileError(file, "[[blocks]]", None, f"a loop of order at most "
                            f"{MAX_LOOP_ORDER} (this one has order {order}, the sum of its "
                            "blocks' orders: its characteristic polynomial's coefficients "
                            "would lose its roots in double precision, and overflow near "
                            "order 100)")
