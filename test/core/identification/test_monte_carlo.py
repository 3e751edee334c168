"""Monte Carlo over 100 noise seeds on hidden-truth data: the 95 % intervals of omega and zeta cover
the truth about 95 % of the time, and the errors stay within twice the Cramer-Rao bound computed
here from the Fisher information of the independent simulator (the issue's aim)."""

import numpy as np
import pytest

from flexmotion_ros.core.identification import SensorOutput, identify

from .truth import beam_case, crane_case, crb, noise_for_snr, simulate_output, theta_of, two_mass_case

SEEDS = 100


def monte_carlo(case, snr_db: float):
    model, a0, a, u, dt, kind = case()
    y = simulate_output(model, a0, a, u, dt, kind)
    sigma = noise_for_snr(y, snr_db)
    truth = theta_of(model, a0, a)
    bound = np.sqrt(np.diag(crb(truth, a0, u, dt, kind, sigma)))
    t = dt * np.arange(u.size)
    err_w, err_z, cover_w, cover_z = [], [], [], []
    for seed in range(SEEDS):
        noisy = y + sigma * np.random.default_rng(1000 + seed).standard_normal(u.size)
        r = identify(t, u, SensorOutput(samples=noisy, kind=kind), modes=model.n_modes)
        err_w.append([m.omega.value - w for m, w in zip(r.modes, model.omega)])
        err_z.append([m.zeta.value - z for m, z in zip(r.modes, model.zeta)])
        cover_w.append([m.omega.contains(w) for m, w in zip(r.modes, model.omega)])
        cover_z.append([m.zeta.contains(z) for m, z in zip(r.modes, model.zeta)])
    n = model.n_modes
    return (
        np.array(err_w),
        np.array(err_z),
        np.mean(cover_w, axis=0),
        np.mean(cover_z, axis=0),
        bound[1 : 1 + 2 * n : 2],
        bound[2 : 2 + 2 * n : 2],
    )


def check(case, snr_db):
    err_w, err_z, cov_w, cov_z, crb_w, crb_z = monte_carlo(case, snr_db)
    # coverage: binomial(100, 0.95) lies in [0.89, 0.99] with probability 0.995
    assert np.all((cov_w >= 0.88) & (cov_w <= 1.0)), cov_w
    assert np.all((cov_z >= 0.88) & (cov_z <= 1.0)), cov_z
    rms_w = np.sqrt(np.mean(err_w**2, axis=0))
    rms_z = np.sqrt(np.mean(err_z**2, axis=0))
    assert np.all(rms_w <= 2.0 * crb_w), (rms_w, crb_w)
    assert np.all(rms_z <= 2.0 * crb_z), (rms_z, crb_z)
    # efficient, not merely within 2x: the sample rms of 100 draws is within ~15 % of the bound
    assert np.all(rms_w <= 1.3 * crb_w) and np.all(rms_z <= 1.3 * crb_z)
    # no bias beyond what 100 draws can show (3 standard errors of the mean)
    assert np.all(np.abs(err_w.mean(axis=0)) <= 3.0 * crb_w / np.sqrt(SEEDS) + 1e-12)
    assert np.all(np.abs(err_z.mean(axis=0)) <= 3.0 * crb_z / np.sqrt(SEEDS) + 1e-12)


def test_two_mass_noncollocated_encoder_20db():
    check(two_mass_case, 20.0)


def test_crane_cart_encoder_with_drag_30db():
    check(crane_case, 30.0)


@pytest.mark.slow
def test_beam_tip_accelerometer_three_modes_40db():
    check(beam_case, 40.0)
