"""Excitation design: within u_max and the position limits (exact between samples), back where it
started at rest (independent matrix-exponential propagation), and a fit from it at the bound it
predicts; bad requests refused."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core.errors import InputError
from flexmotion_ros.core.identification import SensorOutput, identify
from flexmotion_ros.core.identification.excitation import design_excitation, predicted_std_errors
from flexmotion_ros.core.model.builders import chain, crane
from flexmotion_ros.core.model.modal_model import ModalModel

from .truth import crb, simulate_output, theta_of

WB = ModalModel(b0=0.5, omega=(math.sqrt(2.0),), zeta=(0.0,), b=(1.0,))
CRANE = crane(20.0, 5.0, 2.0, zeta=0.005).model


def fine_states(model, u, dt, start, substeps=16):
    """States at ``substeps`` points per sample (exact, one expm of the whole augmented matrix)."""
    A, B = model.A(), model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt / substeps)
    Phi, Gam = E[:n, :n], E[:n, n]
    x = model.rest_state(start)
    out = [x]
    for uk in u:
        for _ in range(substeps):
            x = Phi @ x + Gam * uk
            out.append(x)
    return np.array(out)


@pytest.mark.parametrize(
    "model,u_max,rate,band,limits",
    [
        (WB, 1.0, 50.0, (0.5, 5.0), (-math.inf, math.inf)),
        (WB, 1.0, 50.0, (0.5, 5.0), (-0.3, 0.4)),
        (CRANE.with_changes(c=-0.1), 50.0, 50.0, (1.0, 6.0), (-1.0, 1.0)),
        (chain([0.5] * 4, [400.0] * 3, [0.4] * 3).model, 10.0, 500.0, (10.0, 80.0), (-0.05, 0.05)),
    ],
)
def test_bounded_within_limits_and_back_at_rest_where_it_started(model, u_max, rate, band, limits):
    start = 0.2 * limits[1] if math.isfinite(limits[1]) else 0.0
    exc = design_excitation(model, u_max, rate, band, position_limits=limits, start=start)
    assert np.max(np.abs(exc.commands)) <= u_max
    assert exc.peak == pytest.approx(u_max) or exc.bound == "position limits"
    X = fine_states(model, exc.commands, exc.dt, start)
    final = X[-1] - model.rest_state(start)
    scale = np.max(np.abs(X - model.rest_state(start)), axis=0)
    assert np.all(np.abs(final) <= 1e-8 * scale), (final, scale)
    p = X[:, 0]
    assert limits[0] <= p.min() and p.max() <= limits[1]
    assert exc.position_range[0] <= p.min() + 1e-12 and p.max() <= exc.position_range[1] + 1e-12
    if exc.bound == "position limits":  # the active limit is reached (to the margin)
        reach = max((p.max() - start) / (limits[1] - start), (start - p.min()) / (start - limits[0]))
        assert reach == pytest.approx(1.0, abs=1e-3)
    assert exc.lines.min() >= band[0] and exc.lines.max() <= band[1]
    assert np.all(exc.commands[-int(0.2 * exc.commands.size) + 1 :] == 0.0)  # the quiet tail


def test_identification_from_the_excitation_of_a_wrong_model_finds_the_true_one():
    """Designed on the planner's model (omega sqrt 2, zeta 0); the machine is 12 % stiffer-sounding with
    zeta 0.03.  The prediction of the standard errors matches the Cramer-Rao bound computed here."""
    exc = design_excitation(WB, 1.0, 20.0, (0.5, 5.0))
    true = WB.with_changes(omega=(1.12 * math.sqrt(2.0),), zeta=(0.03,))
    a = [-0.5]  # encoder on the far mass of the two-mass benchmark
    y = simulate_output(true, 1.0, a, exc.commands, exc.dt)
    sigma = 1e-3
    noisy = y + sigma * np.random.default_rng(9).standard_normal(y.size)
    r = identify(exc.times, exc.commands, SensorOutput(samples=noisy), modes=1, prior=WB, u_max=1.0)
    m = r.modes[0]
    # one seed: within 3 standard errors (95 % coverage is the Monte Carlo test's)
    assert abs(m.omega.value - true.omega[0]) <= 3 * m.omega.std_error
    assert abs(m.zeta.value - 0.03) <= 3 * m.zeta.std_error
    bound = np.sqrt(np.diag(crb(theta_of(true, 1.0, a), 1.0, exc.commands, exc.dt, "position", sigma)))
    se_w, se_z = predicted_std_errors(true, exc.commands, exc.dt, sigma, weights=a)
    assert se_w[0] == pytest.approx(bound[1], rel=0.02) and se_z[0] == pytest.approx(bound[2], rel=0.02)
    assert m.omega.std_error == pytest.approx(bound[1], rel=0.1)


@pytest.mark.parametrize(
    "kwargs,parameter",
    [
        (dict(band=(5.0, 0.5)), "band"),
        (dict(band=(0.5, 200.0)), "band"),  # above 0.8 of the Nyquist frequency at 50 Hz (157 rad/s)
        (dict(band=(0.5, 5.0), position_limits=(0.5, 1.0)), "start"),
        (dict(band=(1e-4, 5.0)), "duration"),  # 4 periods of 1e-4 rad/s: far too many samples
        (dict(band=(0.5, 5.0), duration=1.0), "duration"),  # shorter than one period of the band's low end
    ],
)
def test_bad_requests_are_refused_with_the_parameter(kwargs, parameter):
    with pytest.raises(InputError) as info:
        design_excitation(WB, 1.0, 50.0, **kwargs)
    assert info.value.parameter == parameter
