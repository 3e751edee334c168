"""The ROS 2 parameter file, without ROS: read with rcl's typing rules, write doubles as doubles.

The same file serves ``flexmotion plan --config FILE`` and the nodes
(``--ros-args --params-file FILE``)::

    /**:
      ros__parameters:
        model:
          b0: 0.5
          omega: [1.4142135623730951]
        u_max: 1.0

Nested keys are ROS parameter names with dots (``model.b0``).  Every value is
typed by rcl's own rules (:func:`~flexmotion_ros.core.parameters.rcl_scalar`:
``1`` is an integer, ``1.0`` a double) so that ``flexmotion plan`` and the
nodes see the same types; names and types are judged afterwards by
:func:`~flexmotion_ros.core.parameter_checks.check_parameters`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError
from .parameters import KNOWN
from .ros_types import ParameterType, rcl_scalar, ros_type


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"model": {"b0": 1}}`` -> ``{"model.b0": 1}``."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def unflatten(params: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`flatten`."""
    tree: dict[str, Any] = {}
    for name, value in params.items():
        node = tree
        parts = name.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return tree


def _yaml_error(path: Path, exc: yaml.YAMLError, parameter: str) -> ConfigError:
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return ConfigError(parameter, f"{path} is not valid YAML{where}: {problem}")


def _typed_tree(node: yaml.Node, name: str, path: Path, parameter: str) -> Any:
    """A composed YAML node as rcl reads it: mappings nest, scalars and sequences are typed."""
    line = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[str, Any] = {}
        for key, value in node.value:
            if not isinstance(key, yaml.ScalarNode):
                raise ConfigError(parameter, f"{path}: a key must be a name (line {key.start_mark.line + 1})")
            out[key.value] = _typed_tree(value, f"{name}.{key.value}" if name else key.value, path, parameter)
        return out if out else None  # 'x: {}' declares x with no value in rcl
    if isinstance(node, yaml.SequenceNode):
        items: list[Any] = []
        stack = list(node.value)
        while stack:  # rcl flattens nested sequences
            item = stack.pop(0)
            if isinstance(item, yaml.SequenceNode):
                stack[:0] = list(item.value)
                continue
            if not isinstance(item, yaml.ScalarNode):
                raise ConfigError(name, f"{path}: a list holds values only (line {item.start_mark.line + 1})")
            items.append(_scalar(item, name, path))
        try:
            ros_type(items)
        except TypeError:
            kinds = ", ".join(dict.fromkeys(str(ros_type(v).value) for v in items))
            names = [
                i.value
                for i in node.value
                if isinstance(i, yaml.ScalarNode) and isinstance(_scalar(i, name, path), bool)
            ]
            quote = (
                f"; rcl reads {', '.join(repr(n) for n in names)} as a bool: quote a name such as 'y'"
                if names and any(isinstance(v, str) for v in items)
                else ""
            )
            raise ConfigError(
                name,
                f"{path} line {line}: list items must all have one type (ROS arrays are homogeneous; "
                f"write doubles as 2.0, not 2), got {kinds}{quote}",
            ) from None
        return items
    return _scalar(node, name, path)


def _scalar(node: yaml.Node, name: str, path: Path) -> Any:
    quoted = node.style in ("'", '"')
    if not quoted and node.value == "":
        raise ConfigError(name, f"{path}: no value at line {node.start_mark.line + 1}")
    return rcl_scalar(node.value, quoted)


def read_parameter_sections(path: str | Path, parameter: str = "config") -> dict[str, dict[str, Any]]:
    """Every section of a ROS 2 parameter file: ``{node name: flat typed ros__parameters}``.

    Values are typed by rcl's rules (:func:`~flexmotion_ros.core.parameters.rcl_scalar`);
    a value rcl refuses (no value, a mixed list), a YAML syntax error or an
    unreadable file raises :class:`ConfigError` naming ``parameter``, the
    file and, for syntax errors, the line and column.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(parameter, f"file not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(parameter, f"{path} is a directory, not a parameter file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(parameter, f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        raise _yaml_error(path, exc, parameter) from None
    if not isinstance(root, yaml.MappingNode):
        raise ConfigError(parameter, f"{path}: expected a mapping of node names to ros__parameters")
    sections: dict[str, dict[str, Any]] = {}
    for key, value in root.value:
        if not isinstance(key, yaml.ScalarNode) or not isinstance(value, yaml.MappingNode):
            raise ConfigError(parameter, f"{path}: expected a mapping of node names to ros__parameters")
        for sub_key, sub in value.value:
            if isinstance(sub_key, yaml.ScalarNode) and sub_key.value == "ros__parameters":
                if not isinstance(sub, yaml.MappingNode):
                    raise ConfigError(
                        parameter,
                        f"{path}: 'ros__parameters' of '{key.value}' must be a mapping of parameter names to values "
                        f"(line {sub.start_mark.line + 1})",
                    )
                tree = _typed_tree(sub, "", path, parameter)
                sections.setdefault(key.value, {}).update(flatten(tree or {}))
    return sections


def read_parameter_file(path: str | Path, node_name: str | None = None, parameter: str = "config") -> dict[str, Any]:
    """Flat parameters from a ROS 2 parameter YAML file, typed by rcl's rules.

    Takes the ``ros__parameters`` of ``/**`` (wildcard) and, if given, of
    ``node_name`` (which override the wildcard), as ROS does.
    """
    path = Path(path)
    data = read_parameter_sections(path, parameter)
    params: dict[str, Any] = {}
    keys = ["/**", "**"]
    if node_name:
        bare = node_name.lstrip("/")
        keys += [bare, "/" + bare]  # ROS matches 'node' and '/node' alike
    found = False
    for key in keys:
        if key in data:
            params.update(data[key])
            found = True
    if not found:
        raise ConfigError(parameter, f"{path}: no '/**: ros__parameters:' section")
    return params


class _Dumper(yaml.SafeDumper):
    pass


def _float_repr(dumper: yaml.SafeDumper, value: float):
    # ROS parameter files need doubles to look like doubles: 2.0, not 2
    if math.isinf(value):
        text = ".inf" if value > 0 else "-.inf"
    elif math.isnan(value):
        text = ".nan"
    else:
        text = repr(float(value))
        if "e" in text and "." not in text.split("e")[0]:
            mant, exp = text.split("e")
            text = f"{mant}.0e{exp}"
    return dumper.represent_scalar("tag:yaml.org,2002:float", text)


def _str_repr(dumper: yaml.SafeDumper, value: str):
    # a name rcl would type as something else (``y`` is a bool to rcl, ``1`` an integer) is quoted
    style = "'" if not isinstance(rcl_scalar(value), str) or value in ("null", "~") else None
    return dumper.represent_scalar("tag:yaml.org,2002:str", value, style=style)


def _list_repr(dumper: yaml.SafeDumper, value: list):
    # lists of values in flow style, [a, b], as ROS parameter files write them (a quoted 'y' would make it block)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", value, flow_style=True)


_Dumper.add_representer(float, _float_repr)
_Dumper.add_representer(str, _str_repr)
_Dumper.add_representer(list, _list_repr)


def dump_parameters(params: Mapping[str, Any], header: str = "") -> str:
    """A ROS 2 parameter file (``/**: ros__parameters:``) for flat parameters."""
    clean = {
        k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and k not in _INT_PARAMS else v)
        for k, v in params.items()
    }
    clean = {
        k: (
            [float(x) if isinstance(x, int) and not isinstance(x, bool) else x for x in v]
            if isinstance(v, (list, tuple))
            else v
        )
        for k, v in clean.items()
    }
    body = yaml.dump(
        {"/**": {"ros__parameters": unflatten(clean)}}, Dumper=_Dumper, sort_keys=False, default_flow_style=None
    )
    return (header + body) if header else body


#: Parameters that are integers, not doubles: the registry's, and the design command's own.
_INT_PARAMS = {p.name for p in KNOWN.values() if p.type is ParameterType.INTEGER} | {"design.force_on"}
