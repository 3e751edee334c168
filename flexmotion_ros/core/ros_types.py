"""ROS 2's parameter types and ``rcl_yaml_param_parser``'s typing rules, without ROS.

:func:`rcl_scalar` types one YAML scalar as rcl does (an integer literal is an
INTEGER, ``1.0`` a DOUBLE, ``yes`` a BOOL, a quoted value a STRING, ...);
:func:`ros_type` names the ROS type of a Python value; the registry of names
(:mod:`.parameters`) checks values against them.
"""

from __future__ import annotations

import enum
import math
import re
import sys
from typing import Any

from .errors import ConfigError


class ParameterType(enum.Enum):
    """A ROS 2 parameter type (``rcl_interfaces/ParameterType``), by its name."""

    BOOL = "bool"
    INTEGER = "integer"
    DOUBLE = "double"
    STRING = "string"
    BOOL_ARRAY = "bool_array"
    INTEGER_ARRAY = "integer_array"
    DOUBLE_ARRAY = "double_array"
    STRING_ARRAY = "string_array"


_ELEMENT = {
    ParameterType.BOOL_ARRAY: ParameterType.BOOL,
    ParameterType.INTEGER_ARRAY: ParameterType.INTEGER,
    ParameterType.DOUBLE_ARRAY: ParameterType.DOUBLE,
    ParameterType.STRING_ARRAY: ParameterType.STRING,
}
ARRAY_OF = {v: k for k, v in _ELEMENT.items()}


def ros_type(value: Any) -> ParameterType | None:
    """The ROS type of a plain value (``None`` or ``[]``: not set); ``TypeError`` for a mixed list."""
    if value is None:
        return None
    if isinstance(value, bool):
        return ParameterType.BOOL
    if isinstance(value, int):
        return ParameterType.INTEGER
    if isinstance(value, float):
        return ParameterType.DOUBLE
    if isinstance(value, str):
        return ParameterType.STRING
    if isinstance(value, (list, tuple)):
        if not value:
            return None
        kinds = {ros_type(v) for v in value}
        if len(kinds) != 1 or next(iter(kinds)) not in ARRAY_OF:
            raise TypeError(f"a list of mixed or unsupported types: {value!r}")
        return ARRAY_OF[next(iter(kinds))]
    raise TypeError(f"unsupported value {value!r}")


def with_type(value: Any) -> str:
    t = ros_type(value)
    return f"the {t.value.replace('_', ' ')} {value!r}" if t is not None else repr(value)


def a_type(t: ParameterType) -> str:
    """``"a double"``, ``"an integer"``, ``"a double array"``."""
    text = t.value.replace("_", " ")
    return ("an " if text[0] in "aeiou" else "a ") + text


_TRUE = {"Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"}
_FALSE = {"N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"}
_SPECIAL_FLOATS = {
    ".nan": math.nan,
    ".NaN": math.nan,
    ".NAN": math.nan,
    **{f"{s}.{w}": (-math.inf if s == "-" else math.inf) for s in ("", "+", "-") for w in ("inf", "Inf", "INF")},
}
#: What C ``strtol(s, &end, 0)`` consumes whole: decimal, ``0x`` hex, ``0`` octal.
_C_INT = re.compile(r"[ \t\n\v\f\r]*[+-]?(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
#: What C ``strtod`` consumes whole (decimal and hex floats, inf, infinity, nan).
_C_FLOAT = re.compile(
    r"[ \t\n\v\f\r]*[+-]?("
    r"([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?"
    r"|0[xX]([0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)([pP][+-]?[0-9]+)?"
    r"|inf|infinity|nan(\([0-9A-Za-z_]*\))?)",
    re.IGNORECASE,
)
_INT64 = 2**63


def rcl_scalar(text: str, quoted: bool = False) -> bool | int | float | str:
    """One YAML scalar typed as ``rcl_yaml_param_parser`` types it.

    Quoted: a string.  Otherwise, in order: ``y/yes/true/on`` (and their
    capitalisations) a BOOL, ``n/no/false/off`` likewise; what C ``strtol``
    (base 0: ``10``, ``0x10``, ``010``) reads whole without overflow an
    INTEGER; ``.inf``, ``.nan`` and what ``strtod`` reads whole without
    overflow a DOUBLE; anything else a STRING (``null`` and ``~`` included).
    """
    if quoted:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    if _C_INT.fullmatch(text):
        body = text.strip()
        sign = -1 if body.startswith("-") else 1
        digits = body.lstrip("+-")
        if digits[:2] in ("0x", "0X"):
            value = int(digits, 16)
        elif len(digits) > 1 and digits.startswith("0"):
            value = int(digits, 8)
        else:
            value = int(digits)
        value *= sign
        if -_INT64 <= value < _INT64:
            return value
        # strtol overflows: rcl falls through to strtod
    if text in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[text]
    if _C_FLOAT.fullmatch(text):
        body = text.strip()
        low = body.lower().lstrip("+-")
        if low.startswith("0x"):
            x = float.fromhex(body)
        elif low.startswith("nan"):
            x = math.nan
        else:
            x = float(body)
        finite_text = not low.startswith(("inf", "nan"))
        mantissa = re.split(r"[eEpP]", low)[0]
        underflow = x == 0.0 and any(c not in "0.x" for c in mantissa)
        if finite_text and (math.isinf(x) or underflow or 0.0 < abs(x) < sys.float_info.min):
            return text  # strtod sets ERANGE: rcl keeps the text as a string
        return x
    return text


def parse_parameter_value(text: str, name: str = "--option") -> Any:
    """A command-line value (``-p NAME:=VALUE``, ``--option NAME=VALUE``) typed by the rcl rules.

    A flow list ``[1.0, 2.0]`` becomes a homogeneous list; a mixed one raises
    :class:`ConfigError` naming ``name``.
    """
    stripped = text.strip()
    if stripped.startswith("[") and stripped.endswith("]"):
        inner = stripped[1:-1].strip()
        if not inner:
            return []
        items = [rcl_scalar(*_unquote(part.strip())) for part in inner.split(",")]
        try:
            ros_type(items)
        except TypeError:
            raise ConfigError(name, f"list items must all have one type (write doubles as 2.0), got {text!r}") from None
        return items
    return rcl_scalar(*_unquote(stripped))


def _unquote(text: str) -> tuple[str, bool]:
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1], True
    return text, False
