"""Maximum-likelihood refinement on the exact ZOH response, and the parameters' covariance.

Under white Gaussian noise of standard deviation ``sigma_j`` on output ``j``
the likelihood is maximised by the weighted least squares
``min sum_j |y_j - yhat_j(theta)|^2 / sigma_j^2``, solved by
a trust-region reflective Gauss-Newton method (:func:`scipy.optimize.least_squares`,
``method="trf"``, inside a box of stable sub-Nyquist models)
with the exact Jacobian of
:meth:`~flexmotion_ros.core.identification.forward.ForwardModel.predict_and_jacobian`.
Each ``sigma_j`` is re-estimated from its residual (``RSS_j / (N - P_j)``)
and the fit repeated until the weights settle (one output: no repetition).

The covariance is the inverse of the Gauss-Newton Fisher information
``J^T W J`` at the optimum, ``W = diag(1 / sigma_j^2)``: the Cramer-Rao bound
evaluated at the estimate, which the maximum-likelihood estimate attains
asymptotically.  It is computed from the column-scaled Jacobian by an SVD,
so parameters of very different sizes (``b0`` in 1/kg, ``omega`` in rad/s,
an offset in m) do not lose precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .forward import ForwardModel

#: The optimiser stops when the relative change of the cost or the step is below this.
LM_TOL = 1e-10
#: Most model evaluations per round: a sound start converges in 5-20; a spurious mode wanders.
MAX_EVALUATIONS = 60
#: Lowest damping ratio searched (see :func:`parameter_bounds`).
MAX_NEGATIVE_ZETA = 0.1
#: Re-weighting rounds for several outputs (the noise levels converge in two or three).
REWEIGHT_ROUNDS = 4


@dataclass(frozen=True, kw_only=True)
class Fit:
    """A refined fit.

    Attributes
    ----------
    theta : ndarray
        Parameters (layout of :class:`ForwardModel`).
    covariance : ndarray
        Their covariance (inverse Fisher information at ``theta``).
    rss : ndarray
        Residual sum of squares per output.
    sigma : ndarray
        Noise standard deviation per output (output units).
    residuals : tuple of ndarray
        ``y_j - yhat_j`` per output.
    evaluations : int
        Model evaluations used.
    success : bool
        The optimiser met its tolerance.
    """

    theta: np.ndarray
    covariance: np.ndarray
    rss: np.ndarray
    sigma: np.ndarray
    residuals: tuple[np.ndarray, ...]
    evaluations: int
    success: bool

    @property
    def std_errors(self) -> np.ndarray:
        """Standard errors of ``theta``."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def log_likelihood_term(self, samples: int) -> float:
        """``sum_j N log(RSS_j / N)``: the data term of an information criterion."""
        return float(np.sum(samples * np.log(np.maximum(self.rss, 1e-300) / samples)))


def covariance(J: np.ndarray) -> np.ndarray:
    """``(J^T J)^{-1}`` of a weighted Jacobian, by an SVD of its column-scaled form (pseudo-inverse if singular)."""
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0.0] = 1.0
    _, S, Vt = np.linalg.svd(J / scale, full_matrices=False)
    tiny = S <= S[0] * 1e-13
    inv = np.where(tiny, np.inf, 1.0 / np.where(tiny, 1.0, S) ** 2)
    inv[tiny] = 0.0
    cov = (Vt.T * inv) @ Vt
    cov = cov / scale[:, None] / scale[None, :]
    if tiny.any():  # a direction the data do not determine: its parameters get an infinite variance
        bad = np.abs(Vt[tiny]).max(axis=0) > 1e-6
        cov[bad, :] = np.inf
        cov[:, bad] = np.inf
    return cov


def parameter_bounds(fm: ForwardModel) -> tuple[np.ndarray, np.ndarray]:
    """Box that keeps the search among stable, sub-Nyquist models (never active at a sound optimum).

    ``zeta >= -MAX_NEGATIVE_ZETA``: an unstable mode's response grows without
    bound and overflows; slightly negative values stay allowed so that an
    undamped mode's estimate is unbiased and its interval honest.
    """
    lo = np.full(fm.n_params, -np.inf)
    hi = np.full(fm.n_params, np.inf)
    nyq = fm.data.nyquist
    for i in range(fm.n_modes):
        lo[1 + 2 * i], hi[1 + 2 * i] = 1e-6 * nyq, nyq
        lo[2 + 2 * i], hi[2 + 2 * i] = -MAX_NEGATIVE_ZETA, 1.0
    lo[0] = -nyq
    hi[0] = nyq * 1e-3
    return lo, hi


def refine(fm: ForwardModel, theta0: np.ndarray, sigma0: np.ndarray | None = None) -> Fit:
    """Weighted nonlinear least squares from ``theta0``; see the module docstring.

    Parameters
    ----------
    fm : ForwardModel
    theta0 : ndarray
        Start (a first estimate with its best linear parameters).
    sigma0 : ndarray, optional
        Noise levels to weight the outputs by at first (default: the start's residual levels).
    """
    n = fm.data.samples
    m = fm.n_outputs
    theta = np.asarray(theta0, dtype=float)
    if sigma0 is None:
        sigma0 = np.array([np.std(fm.y[j] - p) for j, p in enumerate(fm.predict(theta))])
    sigma = np.maximum(np.asarray(sigma0, dtype=float), 1e-300)
    evaluations = 0
    success = True
    cache: dict = {}
    bounds = parameter_bounds(fm)
    theta = np.clip(theta, bounds[0], bounds[1])

    def evaluate(th: np.ndarray):
        key = th.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = fm.predict_and_jacobian(th)
        return cache[key]

    for _ in range(REWEIGHT_ROUNDS if m > 1 else 1):
        w = 1.0 / sigma

        def fun(th: np.ndarray, w: np.ndarray = w) -> np.ndarray:
            preds, _ = evaluate(th)
            return np.concatenate([(fm.y[j] - preds[j]) * w[j] for j in range(m)])

        def jac(th: np.ndarray, w: np.ndarray = w) -> np.ndarray:
            _, jacs = evaluate(th)
            return np.vstack([-jacs[j] * w[j] for j in range(m)])

        with np.errstate(over="ignore", invalid="ignore"):
            sol = least_squares(
                fun,
                theta,
                jac=jac,
                method="trf",
                bounds=bounds,
                x_scale="jac",
                xtol=LM_TOL,
                ftol=LM_TOL,
                gtol=LM_TOL,
                max_nfev=MAX_EVALUATIONS,
            )
        theta = sol.x
        evaluations += int(sol.nfev) + int(sol.njev or 0)
        success = success and sol.status > 0
        preds, jacs = evaluate(theta)
        rss = np.array([float(np.sum((fm.y[j] - preds[j]) ** 2)) for j in range(m)])
        # degrees of freedom: each output's share of the parameters it depends on
        dof = n - np.array([np.count_nonzero(np.any(jacs[j] != 0.0, axis=0)) for j in range(m)])
        new_sigma = np.sqrt(rss / np.maximum(dof, 1))
        settled = np.allclose(new_sigma, sigma, rtol=1e-3)
        sigma = new_sigma
        if settled:
            break
    Jw = np.vstack([jacs[j] / sigma[j] for j in range(m)])
    residuals = tuple(fm.y[j] - preds[j] for j in range(m))
    return Fit(
        theta=theta,
        covariance=covariance(Jw),
        rss=rss,
        sigma=sigma,
        residuals=residuals,
        evaluations=evaluations,
        success=bool(success),
    )
