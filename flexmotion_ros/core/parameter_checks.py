"""The checks of a parameter set against the registry of :mod:`.parameters`.

Every name a parameter file, ``flexmotion ... --option`` or a node carries is
checked here: known (:func:`check_name`, with the closest known name), of its
declared ROS type (:func:`check_type`), one of its choices
(:func:`check_choice`), and the options a method requires present
(:func:`check_required_options`); :func:`check_parameters` is the one check of
a whole set.

Types follow ``rcl_yaml_param_parser`` (what ``--params-file`` does,
:mod:`.ros_types`): :func:`~.ros_types.rcl_scalar` types one YAML scalar as rcl does (an integer literal is
an INTEGER, ``1.0`` a DOUBLE, ``yes`` a BOOL, a quoted value a STRING, ...).
The verdict on an integer where a double is declared is **refuse**, in the
command line and the nodes alike: rclpy refuses it at declaration and at
``ros2 param set``, so accepting it in a file would only move the refusal to
run time.  The error names the key and says to write ``2.0``.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from .errors import ConfigError
from .parameters import KNOWN, KNOWN_PREFIXES, required_options
from .ros_types import ParameterType, a_type, ros_type, with_type


def check_required_options(method: str, options: Mapping[str, Any]) -> None:
    """Raise :class:`ConfigError` naming the first option ``method`` requires and ``options`` lacks."""
    for p in required_options(method):
        if options.get(p.name) is None:
            raise ConfigError(
                p.name, f"required by method {method}: set '{p.name}' ({p.allowed}) in the parameter file"
            )


def is_known(name: str, extra: Iterable[str] = ()) -> bool:
    """Whether ``name`` is a known parameter (or in ``extra``, or under a :data:`KNOWN_PREFIXES` namespace)."""
    return name in KNOWN or name in set(extra) or name.startswith(KNOWN_PREFIXES)


#: How alike (difflib ratio) a mistyped name and a valid one must be for the valid one to be suggested.
CLOSE_NAME_CUTOFF = 0.6


def closest_name(name: str, valid: Iterable[str]) -> str | None:
    """The valid name closest to a mistyped ``name`` (None if none is close): the one did-you-mean helper."""
    match = difflib.get_close_matches(name, sorted(set(valid)), n=1, cutoff=CLOSE_NAME_CUTOFF)
    return match[0] if match else None


def closest_hint(name: str, valid: Iterable[str]) -> str:
    """`` (closest: 'x')`` for a mistyped ``name``, or ``""`` if nothing is close."""
    match = closest_name(name, valid)
    return f" (closest: {match!r})" if match is not None else ""


def check_name(name: str, extra: Iterable[str] = ()) -> None:
    """Raise :class:`ConfigError` for an unknown name, with the closest known one."""
    extra = set(extra)
    if is_known(name, extra):
        return
    close = closest_name(name, set(KNOWN) | extra)
    hint = f"did you mean {close}?" if close else "see flexmotion_ros/core/parameters.py for the known names"
    raise ConfigError(name, f"unknown parameter; {hint}")


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` as one of ``choices``, else :class:`ConfigError` naming ``name``, the choices and the closest.

    The one text for a value outside its choices, in the command line and the nodes alike.
    """
    text = str(value)
    if text not in choices:
        raise ConfigError(name, f"must be one of {list(choices)}, got {value!r}{closest_hint(text, choices)}")
    return text


def check_type(name: str, value: Any) -> None:
    """Raise :class:`ConfigError` if ``value`` is not of the ROS type the registry declares for ``name``.

    A string parameter with fixed :attr:`ParameterInfo.choices` must also be one of them.

    Unregistered names (``design.*``, ``qos_overrides.*``) and unset values pass.
    """
    info = KNOWN.get(name)
    if info is None:
        return
    try:
        t = ros_type(value)
    except TypeError:
        raise ConfigError(
            name, f"must be {a_type(info.type)} ({info.allowed}); a list needs one type, got {value!r}"
        ) from None
    if t is None:
        return
    if t == info.type or t in info.alternatives:
        if info.choices:
            check_choice(name, value, info.choices)
        return
    hint = ""
    if info.type == ParameterType.DOUBLE and t == ParameterType.INTEGER:
        hint = f": write {float(value)!r} (ROS types {value!r} as an integer)"
    elif ParameterType.DOUBLE_ARRAY in (info.type, *info.alternatives) and t == ParameterType.INTEGER_ARRAY:
        hint = f": write {[float(v) for v in value]!r} (ROS types {value!r} as integers)"
    kinds = " or ".join(a_type(k) for k in (info.type, *info.alternatives))
    raise ConfigError(name, f"must be {kinds} ({info.allowed}), got {with_type(value)}{hint}")


def check_parameters(params: Mapping[str, Any], extra: Iterable[str] = ()) -> None:
    """Every name known (:func:`check_name`) and of its ROS type (:func:`check_type`); first error raised.

    The one check of a parameter set from a file, ``--option`` or a node's start-up overrides.
    """
    extra = set(extra)
    for name, value in params.items():
        check_name(name, extra)
        check_type(name, value)
