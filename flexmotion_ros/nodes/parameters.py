"""ROS parameters of the nodes: declaring them, their descriptors, validating a set.

What each node declares: :mod:`.parameter_specs` (both),
:mod:`.planner_parameters`, :mod:`.plant_parameters`.

Both nodes read the same parameter file as ``flexmotion plan``
(``--ros-args --params-file FILE``; nested keys such as ``model: {b0: ...}``
become the dotted names ``model.b0``).  Every parameter is declared with a
default and a :class:`ParameterDescriptor` (description with units, a range
where one is meaningful, ``read_only`` where a change cannot apply live).

Validation is the core's: a candidate parameter set is turned into a
:class:`~flexmotion_ros.core.config.PlannerConfig` by
:func:`~flexmotion_ros.core.config.config_from_parameters` (the same function
``flexmotion plan`` uses), so the command line and the nodes accept and
refuse exactly the same files.  The plant adds its model-error and friction
parameters (:func:`.plant_parameters.plant_config_from_parameters`).

Several inputs (issue 12): ``model.inputs`` makes the parameter set a
multi-input machine (:mod:`flexmotion_ros.core.multi_input.dispatch` decides,
for the command line and the nodes alike); ``model.b0``, ``model.c``, ``u_max``
and the initial positions are then double arrays, so they are declared with
dynamic typing (a double for one input, a double array for several).

Changing the number of modes needs ``model.omega``, ``model.zeta`` and
``model.b`` in one atomic set (``SetParametersAtomically``); one at a time,
each intermediate set has mismatched lengths and is refused.
"""

from __future__ import annotations

import array
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..core.errors import ConfigError, FlexmotionError
from ..core.parameter_checks import check_name, check_type
from ..core.parameters import METHOD_OPTIONS


@dataclass(frozen=True)
class Spec:
    """One declared parameter.

    Attributes
    ----------
    name : str
        Dotted ROS parameter name.
    default : Any
        Default value, or a :class:`Parameter.Type` for lists whose default is
        empty (rclpy cannot infer a type from ``[]``).
    description : str
        What it is, with its unit and allowed values.
    read_only : bool
        A change cannot apply live (fixed at start-up).
    fp_range, int_range : tuple, optional
        ``(from, to)`` for a descriptor range.
    dynamic : bool
        Declared with dynamic typing: a double for one input, a double array for several.
    """

    name: str
    default: Any
    description: str
    read_only: bool = False
    fp_range: tuple[float, float] | None = None
    int_range: tuple[int, int] | None = None
    dynamic: bool = False

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=self.read_only, dynamic_typing=self.dynamic)
        if self.fp_range is not None:
            d.floating_point_range = [
                FloatingPointRange(from_value=float(self.fp_range[0]), to_value=float(self.fp_range[1]), step=0.0)
            ]
        if self.int_range is not None:
            d.integer_range = [IntegerRange(from_value=int(self.int_range[0]), to_value=int(self.int_range[1]), step=1)]
        return d


# --------------------------------------------------------------------------- declaration
def plain(value: Any) -> Any:
    """A ROS parameter value as plain Python (arrays become lists)."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def check_overrides(node: Node, extra: Iterable[str] = ()) -> None:
    """The start-up parameters (file, ``-p``, constructor) judged as ``flexmotion plan`` judges a file.

    Every name must be in the core registry (:mod:`flexmotion_ros.core.parameters`) or in
    ``extra`` (the node's own declarations), every registered value of its ROS type: an
    unknown name raises :class:`ConfigError` with the closest known name, a wrong type
    names the key (e.g. ``u_max: 1``: write ``1.0``), with the same text as the command line.
    """
    extra = set(extra)
    for name, value in sorted(parameter_overrides(node).items()):
        if not node.has_parameter(name):  # declared already: known to this node
            check_name(name, extra)
        check_type(name, value)


def declare(node: Node, specs: Iterable[Spec]) -> None:
    """Declare ``specs`` on ``node``; a bad or unknown name in the parameter file raises :class:`ConfigError`."""
    specs = list(specs)
    check_overrides(node, [s.name for s in specs])
    for spec in specs:
        try:
            node.declare_parameter(spec.name, spec.default, spec.descriptor())
        except InvalidParameterTypeException as exc:
            hint = (
                " (write doubles as 2.0, not 2)"
                if isinstance(spec.default, float) or spec.default == Parameter.Type.DOUBLE_ARRAY
                else ""
            )
            raise ConfigError(spec.name, f"wrong type{hint}: {exc}") from None
        except InvalidParameterValueException as exc:
            raise ConfigError(spec.name, str(exc)) from None


def declared_values(node: Node, names: Iterable[str]) -> dict[str, Any]:
    """Current values of declared parameters (unset lists read as ``[]``)."""
    out: dict[str, Any] = {}
    for name in names:
        p = node.get_parameter_or(name, Parameter(name, Parameter.Type.DOUBLE_ARRAY, []))
        out[name] = plain(p.value) if p.value is not None else []
    return out


def parameter_overrides(node: Node) -> dict[str, Any]:
    """Values given to the node at start-up (parameter file, ``-p``, constructor).

    rclpy has no public accessor for these; the attribute has been stable since
    Foxy.  Used only to find method options the planner does not know by name.
    """
    overrides = getattr(node, "_parameter_overrides", {}) or {}
    return {name: plain(p.value) for name, p in overrides.items()}


def option_specs() -> list[Spec]:
    """Every method option of the core registry (:data:`~flexmotion_ros.core.parameters.METHOD_OPTIONS`).

    Declared with their ROS type and no value: unset unless the parameter file
    (or a later set) gives one, so that the node's options are exactly those of
    ``flexmotion plan --config`` on the same file.
    """
    specs = []
    for o in METHOD_OPTIONS:
        required = f"; required by {', '.join(o.required_by)}" if o.required_by else ""
        specs.append(
            Spec(
                o.name,
                Parameter.Type[o.type.name],
                f"option of the planning method (see 'method'): {o.description} ({o.allowed}); read by "
                f"{', '.join(o.methods)}{required}; unset: the method's default. A change applies to the next goal.",
            )
        )
    return specs


def declare_method_options(node: Node, known: Iterable[str]) -> list[str]:
    """Declare every method option (:func:`option_specs`) not in ``known``; return their names.

    Declared up front with descriptors, so that ``ros2 param set`` can give a
    method its options (``method`` with ``coulomb_force`` in one atomic call).
    The start-up parameters were checked by :func:`declare` (unknown names and
    wrong types refused).
    """
    known = set(known)
    specs = [s for s in option_specs() if s.name not in known and not node.has_parameter(s.name)]
    declare(node, specs)
    return [s.name for s in specs]


def validating_callback(
    current: Callable[[], dict[str, Any]], validate: Callable[[dict[str, Any]], Any]
) -> Callable[[list[Parameter]], SetParametersResult]:
    """An on-set-parameters callback: build the whole candidate set and validate it.

    ``current()`` returns the node's parameter values; ``validate(candidate)``
    raises :class:`FlexmotionError` to refuse (its text becomes ``reason``).
    """

    def callback(params: list[Parameter]) -> SetParametersResult:
        candidate = current()
        for p in params:
            candidate[p.name] = plain(p.value) if p.value is not None else []
            try:  # the registry's ROS type: rclpy no longer checks the dynamically typed ones (u_max, model.b0, ...)
                check_type(p.name, candidate[p.name])
            except ConfigError as exc:
                return SetParametersResult(successful=False, reason=f"wrong type: {exc}")
        try:
            validate(candidate)
        except FlexmotionError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        except (TypeError, ValueError) as exc:  # e.g. a string where a number belongs
            return SetParametersResult(successful=False, reason=f"invalid value: {exc}")
        return SetParametersResult(successful=True)

    return callback
