"""``identify``: the modal model from a measured input and output(s), with its uncertainty.

1. Check the data (:func:`~flexmotion_ros.core.identification.data.check_data`).
2. First estimates of ``N`` modes by OKID/ERA on block averages
   (:func:`~flexmotion_ros.core.identification.initial.initial_estimates`), ranked
   by the exact full-rate fit with the best linear parameters.
3. Refine the best few by maximum likelihood on the exact zero-order-hold
   response (:func:`~flexmotion_ros.core.identification.refine.refine`); keep the
   best.  Standard errors from the Fisher information.
4. The number of modes, unless given: ``N = 0 .. max_modes`` are all fitted
   and the smallest Bayesian information criterion
   ``sum_j N log(RSS_j / N) + P log(M N)`` wins (``P`` parameters, ``M``
   outputs of ``N`` samples), among the fits whose every mode stands out
   (gain at least :data:`MIN_GAIN_T` standard errors from 0).  A spurious
   mode lowers the residual by about one noise variance per parameter, far
   less than its ``log(M N)`` penalty.  The search stops early at the first
   count (at least one) whose modes all stand out and whose residuals are as
   white as noise: nothing is left for another mode to explain.  The Hankel
   singular values of the winning realization are reported beside it.
5. Refuse what the data cannot support: a mode at or above
   :data:`NYQUIST_FRACTION` of the Nyquist frequency (it may be aliased; a
   prior model's mode there is refused before fitting), a mode that does not
   complete :data:`MIN_CYCLES` cycles within the record, a mode whose frequency
   is undetermined (relative standard error above :data:`MAX_OMEGA_RSE`).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..model.modal_model import ModalModel
from .data import IdentificationData, SensorOutput, check_data
from .forward import ForwardModel
from .initial import Start, initial_estimates
from .refine import Fit, refine
from .result import Estimate, IdentificationResult, ModeEstimate, ModeSelection, OutputFit, finite_or_inf

#: Modes above this fraction of the Nyquist frequency are refused (aliasing cannot be ruled out).
NYQUIST_FRACTION = 0.8
#: A mode must complete this many cycles within the record.
MIN_CYCLES = 2.0
#: A mode whose frequency's relative standard error exceeds this is not identified from the data.
MAX_OMEGA_RSE = 0.1
#: A mode must stand out: its gain at least this many standard errors from 0 (a mode fitted to white
#: noise at the best of ~N/2 frequencies reaches about sqrt(2 ln N), 4 for 10^4 samples).
MIN_GAIN_T = 6.0
#: A mode whose damping ratio comes out at least this is not a vibration mode.
OVERDAMPED_ZETA = 0.9
#: A damping ratio below minus this is a growing mode, not noise around an undamped one.
UNSTABLE_ZETA = 0.05
#: Most modes tried when the number is selected.
DEFAULT_MAX_MODES = 4
#: Refined starts per number of modes.
STARTS = 3
#: A fit whose residual autocorrelation stays below this over sqrt(N) at every lag checked is
#: taken as final (white noise exceeds it at one of 20 lags about once in 100 000 fits).
WHITE_ENOUGH = 4.5
#: Residual autocorrelation lags checked.
WHITENESS_LAGS = 20


def _normalise(fm: ForwardModel, fit: Fit) -> tuple[np.ndarray, np.ndarray]:
    """``(omega, zeta) -> (-omega, -zeta)`` is the same mode: make every ``omega > 0``; sort by frequency."""
    theta = fit.theta.copy()
    cov = fit.covariance.copy()
    n = fm.n_modes
    sign = np.ones(theta.size)
    for i in range(n):
        if theta[1 + 2 * i] < 0.0:
            sign[1 + 2 * i] = sign[2 + 2 * i] = -1.0
    theta = theta * sign
    cov = cov * sign[:, None] * sign[None, :]
    c, omega, zeta, b0, gains, offsets = fm.split(theta)
    order = np.argsort(omega)
    perm = list(range(theta.size))
    k = fm.n_nonlinear
    for new, old in enumerate(order):
        perm[1 + 2 * new] = 1 + 2 * old
        perm[2 + 2 * new] = 2 + 2 * old
        for j in range(fm.n_outputs):
            perm[k + 1 + j * n + new] = k + 1 + j * n + old
    perm = np.array(perm)
    return theta[perm], cov[np.ix_(perm, perm)]


def _describe(start: Start) -> str:
    if not start.omega:
        return "the rigid body alone (c scanned)"
    if start.block == PRIOR_BLOCK:
        return "the prior model"
    if start.block == 0:
        return "residual spectra"
    return f"ERA (blocks of {start.block} samples, order {start.order})"


#: ``Start.block`` of the prior model's proposal (0 is the spectral one, >= 1 a realization's block size).
PRIOR_BLOCK = -1


def _fit_modes(data: IdentificationData, n_modes: int, prior: ModalModel | None) -> tuple[Fit | None, np.ndarray, str]:
    """Best refined fit of ``n_modes`` modes, the Hankel singular values, and which first estimate led to it."""
    extra: tuple[Start, ...] = ()
    if prior is not None and prior.n_modes == n_modes and n_modes > 0:
        extra = (Start(omega=tuple(prior.omega), zeta=tuple(prior.zeta), c=prior.c, block=PRIOR_BLOCK),)
    starts, svs = initial_estimates(data, n_modes, keep=STARTS, extra=extra)
    fm = ForwardModel(data, n_modes)
    best: Fit | None = None
    origin = ""
    for st in starts:
        theta0, _ = fm.linear_fit(st.c, st.omega, st.zeta)
        fit = refine(fm, theta0)
        if best is None or fit.log_likelihood_term(data.samples) < best.log_likelihood_term(data.samples):
            best, origin = fit, _describe(st)
        if fit.success and _white(fit):
            break  # residuals as white as noise: nothing left for another start to explain
    return best, svs, origin


def _whiteness(r: np.ndarray) -> float:
    r = r - r.mean()
    d = float(r @ r)
    if d == 0.0:
        return 0.0
    lags = min(WHITENESS_LAGS, r.size - 1)
    return float(max(abs(float(r[k:] @ r[:-k])) / d for k in range(1, lags + 1)))


def gain_significance(fm: ForwardModel, fit: Fit) -> np.ndarray:
    """Per mode, the largest ``|gain| / std_error`` over the outputs (how clearly the data show it)."""
    _, _, _, _, gains, _ = fm.split(fit.theta)
    _, _, _, _, se, _ = fm.split(fit.std_errors)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(se > 0.0, np.abs(gains) / se, 0.0)
    return t.max(axis=0) if t.size else np.zeros(0)


def _white(fit: Fit) -> bool:
    """Every output's residual autocorrelation below :data:`WHITE_ENOUGH` / sqrt(N) at lags 1-20."""
    return all(_whiteness(r) <= WHITE_ENOUGH / math.sqrt(r.size) for r in fit.residuals)


def _check_modes(data: IdentificationData, omega, zeta, se_omega, significance) -> None:
    for i, t in enumerate(significance):
        if not t >= MIN_GAIN_T:
            raise InputError(
                "data.input",
                f"does not show mode {i} (at {omega[i]:.6g} rad/s its gain is {t:.2g} standard errors from 0, "
                f"need {MIN_GAIN_T:g}): the data show fewer modes; ask for fewer, or excite that band "
                "(flexmotion excite) and record longer",
            )
    for i, (w, z, s) in enumerate(zip(omega, zeta, se_omega)):
        if z <= -UNSTABLE_ZETA:
            raise InputError(
                "data.output",
                f"mode {i} came out growing (zeta {z:.3g} < 0): the record shows an unstable oscillation or "
                "dynamics the model lacks (a delay, friction); check the sensor and the input's timing",
            )
        if z >= OVERDAMPED_ZETA:
            raise InputError(
                "data.input",
                f"mode {i} came out critically damped (zeta {z:.3g}): the data show no lightly damped mode there; "
                "ask for fewer modes",
            )
        if w >= NYQUIST_FRACTION * data.nyquist:
            raise InputError(
                "data.time",
                f"mode {i} at {w:.6g} rad/s is at or above {NYQUIST_FRACTION} of the Nyquist frequency "
                f"pi/dt = {data.nyquist:.6g} rad/s: it may be aliased; sample faster",
            )
        if w * math.sqrt(max(1.0 - z * z, 0.0)) * data.duration < 2.0 * math.pi * MIN_CYCLES:
            raise InputError(
                "data",
                f"too short: mode {i} at {w:.6g} rad/s completes fewer than {MIN_CYCLES:g} cycles in "
                f"{data.duration:.6g} s; record at least {2.0 * math.pi * MIN_CYCLES / w:.6g} s",
            )
        if not (math.isfinite(s) and s <= MAX_OMEGA_RSE * w):
            raise InputError(
                "data.input",
                f"does not excite mode {i} enough: omega = {w:.6g} rad/s +- {s:.3g} (more than "
                f"{MAX_OMEGA_RSE:.0%}); excite around it (flexmotion excite) or record longer",
            )


def identify(
    time,
    u,
    outputs: SensorOutput | Sequence[SensorOutput],
    *,
    modes: int | None = None,
    max_modes: int = DEFAULT_MAX_MODES,
    prior: ModalModel | None = None,
    u_max: float | None = None,
) -> IdentificationResult:
    """Identify the modal model from one held input and measured output(s).

    Parameters
    ----------
    time : array_like
        Uniform sample times (s).
    u : array_like
        Input held from each time stamp to the next (N); the machine is at rest before the first.
    outputs : SensorOutput or sequence of SensorOutput
        Measured outputs (position, velocity, acceleration of physical coordinates).
    modes : int, optional
        Number of vibration modes; default: selected (module docstring).
    max_modes : int
        Most modes tried when selecting.
    prior : ModalModel, optional
        A model believed before: its modes are refused if above the Nyquist
        frequency, and tried as one more first estimate.
    u_max : float, optional
        Actuator bound; an input beyond it is refused (saturated actuator).

    Returns
    -------
    IdentificationResult

    Raises
    ------
    InputError
        Data it cannot identify from (see :func:`check_data` and the module docstring).
    """
    t_start = _time.perf_counter()
    outs = (outputs,) if isinstance(outputs, SensorOutput) else tuple(outputs)
    if modes is not None and (isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) or modes < 0):
        raise InputError("modes", f"must be an integer >= 0, got {modes!r}")
    if isinstance(max_modes, bool) or not isinstance(max_modes, (int, np.integer)) or max_modes < 0:
        raise InputError("max_modes", f"must be an integer >= 0, got {max_modes!r}")
    counts = [int(modes)] if modes is not None else list(range(int(max_modes) + 1))
    n_params = 2 + 3 * counts[0] + len(outs) * (1 + counts[0])
    data = check_data(time, u, outs, u_max=u_max, parameters=n_params)
    if prior is not None:
        for i, (w, z) in enumerate(zip(prior.omega, prior.zeta)):
            if w * math.sqrt(1.0 - z * z) * data.duration < 2.0 * math.pi * MIN_CYCLES:
                raise InputError(
                    "data",
                    f"too short: model.omega[{i}] = {w:.6g} rad/s completes fewer than {MIN_CYCLES:g} cycles in "
                    f"{data.duration:.6g} s; record at least {2.0 * math.pi * MIN_CYCLES / w:.6g} s",
                )
            if w >= NYQUIST_FRACTION * data.nyquist:
                raise InputError(
                    f"model.omega[{i}]",
                    f"{w:.6g} rad/s is at or above {NYQUIST_FRACTION} of the Nyquist frequency pi/dt = "
                    f"{data.nyquist:.6g} rad/s of data.time: it would alias; sample faster",
                )
    fits: dict[int, tuple[Fit, np.ndarray, str]] = {}
    criterion: dict[int, float] = {}
    significant: dict[int, bool] = {}
    stopped = ""
    n_total = data.samples * len(outs)
    for n in counts:
        fit, svs, origin = _fit_modes(data, n, prior)
        if fit is None:
            if modes is not None:
                raise InputError(
                    "modes",
                    f"the data show fewer than {n} lightly damped modes that complete a cycle in the record; "
                    "ask for fewer, record longer, or excite more",
                )
            continue
        fits[n] = (fit, svs, origin)
        fm = ForwardModel(data, n)
        criterion[n] = fit.log_likelihood_term(data.samples) + fm.n_params * math.log(n_total)
        significant[n] = bool(np.all(gain_significance(fm, fit) >= MIN_GAIN_T))
        if modes is None and significant[n] and _white(fit) and n >= 1:
            # nothing left for another mode to explain: more would only pay the criterion's penalty
            stopped = f"stopped at {n}: residual white"
            break
    if modes is not None:
        chosen = int(modes)
    else:  # the smallest BIC among the fits whose every mode stands out (0 modes always does)
        chosen = min((n for n in criterion if significant[n]), key=criterion.get)
    fit, svs, origin = fits[chosen]
    fm = ForwardModel(data, chosen)
    theta, cov = _normalise(fm, fit)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    c, omega, zeta, b0, gains, offsets = fm.split(theta)
    _, se_omega, se_zeta, se_b0, se_gains, se_offsets = fm.split(se)
    with np.errstate(divide="ignore", invalid="ignore"):
        significance = np.where(se_gains > 0.0, np.abs(gains) / se_gains, 0.0).max(axis=0, initial=0.0)
    _check_modes(data, omega, zeta, se_omega, significance)
    preds = fm.predict(theta)
    k = fm.n_nonlinear
    mode_list = tuple(
        ModeEstimate(
            omega=Estimate(value=float(omega[i]), std_error=finite_or_inf(float(se_omega[i]))),
            zeta=Estimate(value=float(zeta[i]), std_error=finite_or_inf(float(se_zeta[i]))),
            gains=tuple(
                Estimate(value=float(gains[j, i]), std_error=finite_or_inf(float(se_gains[j, i])))
                for j in range(fm.n_outputs)
            ),
        )
        for i in range(chosen)
    )
    out_fits = []
    for j, o in enumerate(data.outputs):
        r = o.samples - preds[j]
        spread = float(np.linalg.norm(o.samples - o.samples.mean()))
        out_fits.append(
            OutputFit(
                name=o.name,
                kind=o.kind,
                rigid_weight=o.rigid_weight,
                offset=Estimate(value=float(offsets[j]), std_error=float(se_offsets[j])),
                noise_std=float(fit.sigma[j]),
                fit_rms=float(np.sqrt(np.mean(r * r))),
                fit_percent=float(100.0 * (1.0 - np.linalg.norm(r) / spread)) if spread > 0 else 0.0,
                residual_correlation=_whiteness(r),
                residual_correlation_bound=1.96 / math.sqrt(data.samples),
            )
        )
    return IdentificationResult(
        b0=Estimate(value=float(b0), std_error=finite_or_inf(float(se[k]))),
        c=Estimate(value=float(c), std_error=finite_or_inf(float(se[0]))),
        modes=mode_list,
        outputs=tuple(out_fits),
        samples=data.samples,
        dt=data.dt,
        solve_time_s=_time.perf_counter() - t_start,
        parameter_names=tuple(fm.names()),
        theta=theta,
        covariance=cov,
        fitted=tuple(preds),
        selection=ModeSelection(
            method="given" if modes is not None else "bic",
            criterion=criterion,
            hankel_singular_values=tuple(float(x) for x in svs),
            note=stopped,
            first_estimate=origin,
        ),
        converged=fit.success,
    )
