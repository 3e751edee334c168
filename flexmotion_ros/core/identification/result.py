"""What an identification returns: estimates with standard errors and 95 % intervals, fit quality,
and what one set of outputs can and cannot determine."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..model.modal_model import ModalModel
from .response import OutputKind

#: Two-sided 95 % quantile of the standard normal distribution.
Z95 = 1.959963984540054

#: Damping ratios are clipped into ``[0, MAX_MODEL_ZETA]`` when a model is built from an estimate.
MAX_MODEL_ZETA = 0.999

IDENTIFIABLE = (
    "b0: the rigid-body input gain, through each sensor's given rigid_weight (1 for any calibrated body coordinate)",
    "c: the rigid-body viscous term",
    "omega and zeta of every mode",
    "gain[j][i] = a_ji b_i: the product of mode i's input gain and its weight in output j",
)

NOT_IDENTIFIABLE = (
    "b_i and a_ji separately: one output fixes only their product (a scale moved from one to the other "
    "changes no measurement); to_model() sets b_i = gain[0][i], i.e. q_i scaled so that output 0 reads it "
    "with weight 1, unless b is given",
    "the physical unit of each modal coordinate q_i (a deflection, an angle): it follows the choice of b_i",
    "mode shapes beyond the measured outputs",
)

PLANNING_NOTE = (
    "rest-to-rest planning (time-optimal, robust, shaped, fixed-time) needs only b0, c, omega and zeta: "
    "each mode's rest condition q_i(T) = q_i'(T) = 0 is homogeneous in b_i, so its scale cancels; b_i "
    "matters only for deflection limits and modal amplitudes in printouts"
)


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """A parameter estimate with its standard error and 95 % interval (``value +- 1.96 std_error``)."""

    value: float
    std_error: float

    @property
    def interval(self) -> tuple[float, float]:
        """95 % confidence interval (normal approximation)."""
        return (self.value - Z95 * self.std_error, self.value + Z95 * self.std_error)

    def contains(self, x: float) -> bool:
        """``x`` lies inside the 95 % interval."""
        lo, hi = self.interval
        return lo <= x <= hi

    def to_dict(self) -> dict[str, object]:
        return {"value": self.value, "std_error": self.std_error, "interval": list(self.interval)}


@dataclass(frozen=True, kw_only=True)
class ModeEstimate:
    """One identified mode.

    Attributes
    ----------
    omega : Estimate
        Undamped natural frequency (rad/s).
    zeta : Estimate
        Damping ratio (-).
    gains : tuple of Estimate
        Per output ``j``, the identifiable product ``a_ji b_i`` (output unit per input unit, e.g. m/(N s^2)).
    """

    omega: Estimate
    zeta: Estimate
    gains: tuple[Estimate, ...]

    def to_dict(self) -> dict[str, object]:
        return {
            "omega": self.omega.value,
            "zeta": self.zeta.value,
            "omega_std_error": self.omega.std_error,
            "zeta_std_error": self.zeta.std_error,
            "omega_interval": list(self.omega.interval),
            "zeta_interval": list(self.zeta.interval),
            "gains": [g.value for g in self.gains],
            "gain_intervals": [list(g.interval) for g in self.gains],
        }


@dataclass(frozen=True, kw_only=True)
class OutputFit:
    """How well one output is fitted.

    Attributes
    ----------
    name, kind :
        The sensor.
    rigid_weight : float
        ``a0`` the fit assumed.
    offset : Estimate
        Sensor offset (output unit).
    noise_std : float
        Estimated white-noise standard deviation (output unit).
    fit_rms : float
        Root mean square of the residual (output unit).
    fit_percent : float
        ``100 (1 - |y - yhat| / |y - mean(y)|)``: 100 is perfect.
    residual_correlation : float
        Largest ``|autocorrelation|`` of the residual at lags 1-20; white noise
        stays below ``residual_correlation_bound`` 19 times in 20 per lag.  A
        larger value says the model misses dynamics (a mode, a delay).
    residual_correlation_bound : float
        ``1.96 / sqrt(N)``.
    """

    name: str
    kind: OutputKind
    rigid_weight: float
    offset: Estimate
    noise_std: float
    fit_rms: float
    fit_percent: float
    residual_correlation: float
    residual_correlation_bound: float

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "kind": str(self.kind),
            "rigid_weight": self.rigid_weight,
            "offset": self.offset.value,
            "noise_std": self.noise_std,
            "fit_rms": self.fit_rms,
            "fit_percent": self.fit_percent,
            "residual_correlation": self.residual_correlation,
            "residual_correlation_bound": self.residual_correlation_bound,
        }


@dataclass(frozen=True, kw_only=True)
class ModeSelection:
    """How the number of modes was decided.

    Attributes
    ----------
    method : str
        ``"given"`` or ``"bic"`` (the smallest Bayesian information criterion over the refined fits).
    criterion : dict
        Number of modes -> BIC (``sum_j N log(RSS_j / N) + P log(M N)``) of its best refined fit.
    hankel_singular_values : tuple of float
        Normalised singular values of the winning realization's Hankel matrix
        (a drop after ``rigid + 2 N`` of them supports ``N`` modes).
    note : str
        Why the search stopped before ``max_modes``, if it did.
    first_estimate : str
        The proposal the chosen fit was refined from: an ERA realization (its
        block size and order), the residual spectra, or the prior model.
    """

    method: str
    criterion: dict = field(default_factory=dict)
    hankel_singular_values: tuple[float, ...] = ()
    note: str = ""
    first_estimate: str = ""

    def to_dict(self) -> dict[str, object]:
        return {
            "method": self.method,
            "criterion": {str(k): v for k, v in self.criterion.items()},
            "hankel_singular_values": list(self.hankel_singular_values[:12]),
            "note": self.note,
            "first_estimate": self.first_estimate,
        }


@dataclass(frozen=True, kw_only=True)
class IdentificationResult:
    """The identified modal model, its uncertainty, and the fit.

    Attributes
    ----------
    b0 : Estimate
        Rigid-body input gain (e.g. 1/kg).
    c : Estimate
        Rigid-body viscous term (1/s); may come out slightly positive from noise
        (:meth:`to_model` clips it to 0).
    modes : tuple of ModeEstimate
        Sorted by frequency.
    outputs : tuple of OutputFit
        Noise level and fit quality per output.
    samples : int
        Samples per signal.
    dt : float
        Sample time (s).
    solve_time_s : float
        Wall time of the identification (s).
    parameter_names : tuple of str
        Names of ``theta`` (layout of :class:`~flexmotion_ros.core.identification.forward.ForwardModel`).
    theta, covariance : ndarray
        All estimated parameters and their covariance (inverse Fisher information).
    fitted : tuple of ndarray
        The fitted response of each output at the samples.
    selection : ModeSelection
    converged : bool
        The optimiser met its tolerance.
    identifiable, not_identifiable : tuple of str
        What the data determine and what they cannot.
    planning_note : str
        What rest-to-rest planning needs from the model.
    """

    b0: Estimate
    c: Estimate
    modes: tuple[ModeEstimate, ...]
    outputs: tuple[OutputFit, ...]
    samples: int
    dt: float
    solve_time_s: float
    parameter_names: tuple[str, ...]
    theta: np.ndarray
    covariance: np.ndarray
    fitted: tuple[np.ndarray, ...]
    selection: ModeSelection
    converged: bool
    identifiable: tuple[str, ...] = IDENTIFIABLE
    not_identifiable: tuple[str, ...] = NOT_IDENTIFIABLE
    planning_note: str = PLANNING_NOTE

    @property
    def n_modes(self) -> int:
        return len(self.modes)

    @property
    def noise_std(self) -> float:
        """Noise standard deviation of the first output (output unit)."""
        return self.outputs[0].noise_std

    @property
    def fit_rms(self) -> float:
        """Residual RMS of the first output (output unit)."""
        return self.outputs[0].fit_rms

    def to_model(self, b: Sequence[float] | None = None, names: Sequence[str] = ()) -> ModalModel:
        """The identified :class:`ModalModel`, ready to plan with.

        Parameters
        ----------
        b : sequence of float, optional
            Modal input gains to use (e.g. a prior model's, whose coordinates
            carry a physical meaning); default ``gain[0][i]`` (see
            :data:`NOT_IDENTIFIABLE`).  Rest-to-rest plans do not depend on them.
        names : sequence of str
            Mode names.

        Notes
        -----
        ``c`` is clipped to ``<= 0`` and each ``zeta`` into ``[0, 0.999]``: a
        model must be physical, and the estimate's interval says how far the
        clip is from the data.
        """
        gains = [m.gains[0].value for m in self.modes] if b is None else [float(x) for x in b]
        return ModalModel(
            b0=self.b0.value,
            c=min(self.c.value, 0.0),
            omega=tuple(m.omega.value for m in self.modes),
            zeta=tuple(min(max(m.zeta.value, 0.0), MAX_MODEL_ZETA) for m in self.modes),
            b=tuple(gains),
            names=tuple(names),
        )

    def to_dict(self) -> dict[str, object]:
        """Plain values for JSON (``b0``, ``c``, ``modes``, ``noise_std``, ``fit_rms``, ``samples``, ...)."""
        return {
            "b0": self.b0.value,
            "b0_std_error": self.b0.std_error,
            "b0_interval": list(self.b0.interval),
            "c": self.c.value,
            "c_std_error": self.c.std_error,
            "c_interval": list(self.c.interval),
            "modes": [m.to_dict() for m in self.modes],
            "noise_std": self.noise_std,
            "fit_rms": self.fit_rms,
            "fit_percent": self.outputs[0].fit_percent,
            "samples": self.samples,
            "dt": self.dt,
            "solve_time_s": self.solve_time_s,
            "converged": self.converged,
            "outputs": [o.to_dict() for o in self.outputs],
            "mode_selection": self.selection.to_dict(),
            "identifiable": list(self.identifiable),
            "not_identifiable": list(self.not_identifiable),
            "planning_note": self.planning_note,
        }


def finite_or_inf(x: float) -> float:
    """``x`` if finite, else ``inf`` (a NaN variance is an undetermined parameter)."""
    return x if math.isfinite(x) else math.inf
