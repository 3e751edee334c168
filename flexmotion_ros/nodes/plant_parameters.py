"""Declared parameters of ``flexmotion_plant`` and the simulated machine they describe.

The plant reads the planner's file (the same model names) and adds its own
``plant.*`` parameters: model error, friction, measurement noise
(:func:`plant_config_from_parameters`, also used by ``flexmotion demo``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from rclpy.parameter import Parameter

from ..core.config import DEFAULTS
from ..core.errors import ConfigError, InputError
from ..core.model.measurement import MeasurementMap, measurement_map, noise_levels
from ..core.multi_input.config import MultiPlannerConfig
from ..core.multi_input.dispatch import AnyModel, config_from_any
from ..core.multi_input.model import MultiModel
from .parameter_specs import command_interface_spec, measurement_specs, model_specs, trajectory_topic_spec
from .parameters import Spec


def plant_specs() -> list[Spec]:
    """Declared parameters of ``flexmotion_plant``."""
    return model_specs(read_only=True) + [
        Spec(
            "rate_hz",
            DEFAULTS["rate_hz"],
            "sample rate (Hz): lockstep advances 1/rate_hz per command; real time integrates and publishes at this rate. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec(
            "lockstep",
            False,
            "true: advance one sample period per command received (deterministic, for tests); false: real time. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "publish_rate_hz",
            0.0,
            "real-time mode: rate (Hz) of the timer that integrates and publishes joint_states; 0: rate_hz. "
            "Commands apply from their arrival times whatever this rate. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e6),
        ),
        Spec(
            "command_timeout",
            0.1,
            "real-time mode: seconds without a command after which zero force is applied, in [0, 3600].",
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "plant.omega_scale",
            Parameter.Type.DOUBLE_ARRAY,
            "model error: true/nominal frequency ratio of each mode (each > 0); empty: 1 for every mode.",
        ),
        Spec(
            "plant.extra_zeta",
            Parameter.Type.DOUBLE_ARRAY,
            "model error: damping ratio added to each mode (each >= 0, total < 1); empty: none.",
        ),
        Spec(
            "plant.coulomb_force",
            0.0,
            "Coulomb friction force (N, >= 0) at the rigid body (eq. 2.11), simulated by core.friction; 0: none.",
            fp_range=(0.0, 1e12),
        ),
        Spec(
            "plant.apply_at",
            "arrival",
            "real-time mode: a command acts from its DDS 'arrival' time at this node, or from its 'send' time at the "
            "publisher (a transport of constant latency; same clock needed, i.e. one machine).",
        ),
        Spec(
            "plant.initial_position",
            0.0,
            "initial rigid-body position (m or rad), at rest; several rigid bodies: one each, or one for all. "
            "Fixed at start-up.",
            read_only=True,
            dynamic=True,
        ),
        Spec(
            "plant.idle_state_period_s",
            0.1,
            "lockstep: while no command has arrived for this long (s), publish the current state on joint_states "
            "this often as a best-effort heartbeat (a reliable subscriber still gets exactly one state per command; "
            "the planner's best-effort measured-state subscription sees the machine alive while idle); 0: never. "
            "Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 3600.0),
        ),
        Spec(
            "plant.input",
            "commands",
            "what drives the plant: 'commands' (one value per sample, lockstep or real time) or 'trajectory' "
            "(joint trajectories on trajectory.topic, played by the plant's own clock with the "
            "joint_trajectory_controller's rule, interpolation none, integrated exactly; lockstep: each one at "
            "once, a replacement rewinds the plant to its first point). Fixed at start-up.",
            read_only=True,
        ),
        command_interface_spec(),
        trajectory_topic_spec(),
        Spec(
            "joint_name",
            "rigid_body",
            "the joint a received trajectory must name. Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "plant.servo_bandwidth",
            0.0,
            "velocity / position joints: bandwidth (rad/s) of a first-order servo tracking the reference; 0: ideal "
            "tracking. Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e12),
        ),
        Spec(
            "plant.disturbance.type",
            "none",
            "a force on the rigid body's input channel (effort joints): 'none', 'impulse' (plant.disturbance.value "
            "N s at plant.disturbance.time_s) or 'step' (value N from time_s on); time from the first non-zero "
            "force (the first move). Fixed at start-up.",
            read_only=True,
        ),
        Spec(
            "plant.disturbance.time_s",
            0.0,
            "when the disturbance acts (s, >= 0), from the first non-zero force (the first move). Fixed at start-up.",
            read_only=True,
            fp_range=(0.0, 1e9),
        ),
        Spec(
            "plant.disturbance.value",
            0.0,
            "the disturbance: impulse (N s) or step (N). Fixed at start-up.",
            read_only=True,
        ),
        *measurement_specs(),
        Spec(
            "plant.noise_std",
            0.0,
            "white noise (standard deviation, units of each channel: m, m/s, m/s^2) added to 'measurements': one "
            "value for every channel or one per channel (a double array), each >= 0; 0: exact readings. Fixed at "
            "start-up.",
            read_only=True,
            dynamic=True,
        ),
        Spec(
            "plant.noise_seed",
            0,
            "seed of the measurement noise (integer >= 0): the same seed gives the same noise. Fixed at start-up.",
            read_only=True,
            int_range=(0, 2**62),
        ),
    ]


# --------------------------------------------------------------------------- plant
@dataclass(frozen=True)
class PlantConfig:
    """The simulated machine.

    Attributes
    ----------
    nominal : ModalModel or MultiModel
        The model in the parameter file (what the planner believes); a
        :class:`MultiModel` when the file sets ``model.inputs``.
    model : ModalModel or MultiModel
        The simulated machine: ``nominal`` with the model errors applied.
    rate_hz : float
        Sample rate (Hz).
    lockstep : bool
    command_timeout : float
        Seconds (s) without command before zero force (real-time mode).
    coulomb_force : float
        Coulomb friction force (N) at the rigid body; 0: none (one input only).
    initial_position : float or ndarray
        Initial rigid-body position (m or rad); one per rigid body for a multi-input model.
    apply_at : str
        Real time: commands act from their ``"arrival"`` or ``"send"`` time.
    measurement : MeasurementMap or None
        The channels published on ``measurements`` (None: the rigid-body position).
    noise_std : tuple of float
        White-noise standard deviation per channel (units of the channel).
    noise_seed : int
        Seed of that noise.
    """

    nominal: AnyModel
    model: AnyModel
    rate_hz: float
    lockstep: bool
    command_timeout: float
    coulomb_force: float
    initial_position: Any
    apply_at: str = "arrival"
    measurement: MeasurementMap | None = None
    noise_std: tuple[float, ...] = ()
    noise_seed: int = 0

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz

    @property
    def inputs(self) -> int:
        """Values per command sample (``m``; 1 for a single-input model)."""
        return self.model.m if isinstance(self.model, MultiModel) else 1


#: What the plant reads of the planner's parameter file.
PLANT_MODEL_NAMES = (
    "model.b0",
    "model.c",
    "model.omega",
    "model.zeta",
    "model.b",
    "model.inputs",
    "model.rigid_bodies",
    "model.mode_names",
    "rate_hz",
)


def _perturbed(nominal: AnyModel, omega: tuple, zeta: tuple) -> AnyModel:
    if isinstance(nominal, MultiModel):
        return replace(nominal, omega=omega, zeta=zeta)
    return nominal.with_changes(omega=omega, zeta=zeta)


def _initial_position(value: Any, nominal: AnyModel) -> Any:
    if isinstance(nominal, MultiModel):
        p = [float(v) for v in (value if isinstance(value, (list, tuple)) else [value])]
        if len(p) == 1:
            p = p * nominal.k
        if len(p) != nominal.k or not all(math.isfinite(v) for v in p):
            raise ConfigError(
                "plant.initial_position",
                f"needs one finite position per rigid body {list(nominal.rigid_bodies)} (or one for all), got {value!r}",
            )
        return np.array(p)
    if isinstance(value, (list, tuple)):
        raise ConfigError("plant.initial_position", f"a single-input model takes one position, got {value!r}")
    p0 = float(value)
    if not math.isfinite(p0):
        raise ConfigError("plant.initial_position", f"must be finite, got {p0}")
    return p0


def plant_config_from_parameters(values: Mapping[str, Any]) -> PlantConfig:
    """Validate the plant's parameters; raise :class:`FlexmotionError` naming the bad one."""
    base = config_from_any({k: values[k] for k in PLANT_MODEL_NAMES if k in values})
    nominal = base.model
    n = nominal.n_modes
    scale = list(values.get("plant.omega_scale") or [])
    extra = list(values.get("plant.extra_zeta") or [])
    if scale and len(scale) != n:
        raise ConfigError("plant.omega_scale", f"needs one factor per mode ({n}) or none, got {len(scale)}")
    if extra and len(extra) != n:
        raise ConfigError("plant.extra_zeta", f"needs one value per mode ({n}) or none, got {len(extra)}")
    for i, s in enumerate(scale):
        if not (math.isfinite(s) and s > 0.0):
            raise ConfigError(f"plant.omega_scale[{i}]", f"must be a finite factor > 0, got {s}")
    for i, z in enumerate(extra):
        if not (math.isfinite(z) and z >= 0.0):
            raise ConfigError(f"plant.extra_zeta[{i}]", f"must be finite and >= 0, got {z}")
    omega = tuple(w * (scale[i] if scale else 1.0) for i, w in enumerate(nominal.omega))
    zeta = tuple(z + (extra[i] if extra else 0.0) for i, z in enumerate(nominal.zeta))
    try:
        model = _perturbed(nominal, omega, zeta)
    except InputError as exc:
        raise ConfigError("plant.omega_scale/extra_zeta", f"the perturbed model is invalid: {exc}") from None
    coulomb = float(values.get("plant.coulomb_force", 0.0))
    if not (math.isfinite(coulomb) and coulomb >= 0.0):
        raise ConfigError("plant.coulomb_force", f"must be finite and >= 0 N, got {coulomb}")
    if coulomb > 0.0 and isinstance(base, MultiPlannerConfig):
        raise ConfigError(
            "plant.coulomb_force", "Coulomb friction is simulated for one input only; set 0.0 for a multi-input model"
        )
    timeout = float(values.get("command_timeout", 0.1))
    if not (math.isfinite(timeout) and timeout >= 0.0):
        raise ConfigError("command_timeout", f"must be finite and >= 0 s, got {timeout}")
    p0 = _initial_position(values.get("plant.initial_position", 0.0), nominal)
    apply_at = str(values.get("plant.apply_at", "arrival"))
    if apply_at not in ("arrival", "send"):
        raise ConfigError("plant.apply_at", f"must be 'arrival' or 'send', got {apply_at!r}")
    # the default map reads every rigid body's position (named as the model names them)
    rigid_names = tuple(nominal.rigid_bodies) if isinstance(nominal, MultiModel) else ("rigid_body",)
    measurement = measurement_map(values, n, rigid_names)
    noise = noise_levels(values.get("plant.noise_std", 0.0), measurement.channels)
    seed = values.get("plant.noise_seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError("plant.noise_seed", f"must be an integer >= 0, got {seed!r}")
    return PlantConfig(
        measurement=measurement,
        noise_std=tuple(float(x) for x in noise),
        noise_seed=int(seed),
        apply_at=apply_at,
        nominal=nominal,
        model=model,
        rate_hz=base.rate_hz,
        lockstep=bool(values.get("lockstep", False)),
        command_timeout=timeout,
        coulomb_force=coulomb,
        initial_position=p0,
    )
