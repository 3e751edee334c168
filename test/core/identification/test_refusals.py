"""Data nothing can be identified from is refused with one line naming the signal and what to do:
too short, no excitation, no response, clipped (saturated) sensors, an input beyond u_max, NaN,
non-uniform time stamps, a mode above the Nyquist frequency, more modes than the data show."""

import numpy as np
import pytest

from flexmotion_ros.core.errors import InputError
from flexmotion_ros.core.identification import SensorOutput, check_data, identify
from flexmotion_ros.core.model.modal_model import ModalModel

from .truth import noise_for_snr, simulate_output, two_mass_case


@pytest.fixture(scope="module")
def run():
    model, a0, a, u, dt, kind = two_mass_case()
    y = simulate_output(model, a0, a, u, dt, kind)
    y = y + noise_for_snr(y, 30.0) * np.random.default_rng(0).standard_normal(u.size)
    return dt * np.arange(u.size), u, y, model


def refused(parameter: str, *fragments: str, **kwargs):
    with pytest.raises(InputError) as info:
        identify(**kwargs)
    err = info.value
    assert err.parameter == parameter, str(err)
    assert "\n" not in str(err)
    for f in fragments:
        assert f in str(err), str(err)
    return err


def test_too_short(run):
    t, u, y, _ = run
    refused("data", "too short", "40 samples", time=t[:40], u=u[:40], outputs=SensorOutput(samples=y[:40]))


def test_too_short_for_the_mode(run):
    """300 samples (6 s) hold less than two periods (8.9 s) of the expected 1.41 rad/s mode."""
    t, u, y, model = run
    refused("data", "too short", "cycles", time=t[:300], u=u[:300], outputs=SensorOutput(samples=y[:300]), prior=model)
    # without a prior the fit finds nothing it can stand behind, and says so
    with pytest.raises(InputError):
        identify(t[:300], u[:300], SensorOutput(samples=y[:300]), modes=1)


def test_no_excitation(run):
    t, _, y, _ = run
    refused("data.input", "no excitation", time=t, u=np.zeros(t.size), outputs=SensorOutput(samples=y))


def test_no_response(run):
    t, u, _, _ = run
    refused("data.output", "does not respond", time=t, u=u, outputs=SensorOutput(samples=np.full(t.size, 0.2)))


def test_clipped_output(run):
    t, u, y, _ = run
    refused("data.output", "clipped", time=t, u=u, outputs=SensorOutput(samples=np.minimum(y, 0.8 * y.max())))
    refused("data.output", "clipped", time=t, u=-u, outputs=SensorOutput(samples=np.maximum(-y, -0.8 * y.max())))


def test_a_machine_at_rest_before_the_excitation_is_not_clipped():
    """Noise-free readings at their minimum while the machine rests before the move are not a rail."""
    u = np.zeros(400)
    u[100:120], u[120:140] = 1.0, -1.0
    y = np.cumsum(np.cumsum(u)) * 1e-3 + 1e-6 * np.random.default_rng(0).standard_normal(400)
    y[:100] = y.min() - 1.0  # at rest at its minimum before the move
    data = check_data(np.arange(400) * 0.01, u, [SensorOutput(samples=y)])
    assert data.samples == 400


def test_a_quantised_encoder_is_not_clipped_but_one_on_its_rail_is():
    t = np.arange(2000) * 0.01
    u = np.sin(0.7 * t)
    y = np.round(np.sin(0.7 * t - 0.3) * 200.0) / 200.0  # 5 mm steps: equal neighbours everywhere
    check_data(t, u, [SensorOutput(samples=y)])
    with pytest.raises(InputError, match="clipped"):
        check_data(t, u, [SensorOutput(samples=np.minimum(y, 0.9))])


def test_input_beyond_u_max_is_a_saturated_actuator(run):
    t, u, y, _ = run
    refused("data.input", "exceeds u_max", "saturated", time=t, u=u, outputs=SensorOutput(samples=y), u_max=0.5)


def test_nan_and_infinite_samples(run):
    t, u, y, _ = run
    bad = y.copy()
    bad[17] = np.nan
    refused("data.output", "NaN", "sample 17", time=t, u=u, outputs=SensorOutput(samples=bad))
    bad_u = u.copy()
    bad_u[3] = np.inf
    refused("data.input", "sample 3", time=t, u=bad_u, outputs=SensorOutput(samples=y))
    bad_t = t.copy()
    bad_t[5] = np.nan
    refused("data.time", "sample 5", time=bad_t, u=u, outputs=SensorOutput(samples=y))


def test_non_uniform_and_non_increasing_time_stamps(run):
    t, u, y, _ = run
    jitter = t.copy()
    jitter[500] += 0.3 * (t[1] - t[0])
    refused("data.time", "not uniform", "sample 500", time=jitter, u=u, outputs=SensorOutput(samples=y))
    back = t.copy()
    back[10] = back[9]
    refused("data.time", "must increase", "sample 10", time=back, u=u, outputs=SensorOutput(samples=y))
    # printed time stamps (rounding far below a sample) are fine
    check_data(np.round(t, 6), u, [SensorOutput(samples=y)])


def test_mismatched_lengths(run):
    t, u, y, _ = run
    refused("data.output", "samples", time=t, u=u, outputs=SensorOutput(samples=y[:-1]))


def test_a_prior_mode_above_nyquist_is_refused_before_fitting(run):
    t, u, y, model = run
    fast = ModalModel(b0=0.5, omega=(200.0,), zeta=(0.01,), b=(1.0,))  # Nyquist of dt = 0.02 s: 157 rad/s
    refused("model.omega[0]", "Nyquist", "sample faster", time=t, u=u, outputs=SensorOutput(samples=y), prior=fast)


def test_an_identified_mode_near_nyquist_is_refused():
    """A mode at 0.9 of the Nyquist frequency: it may be an alias of a faster one."""
    dt = 0.02
    w = 0.9 * np.pi / dt
    model = ModalModel(b0=1.0, omega=(w,), zeta=(0.01,), b=(1.0,))
    u = np.random.default_rng(1).choice([-1.0, 1.0], 2000)
    y = simulate_output(model, 1.0, [1.0], u, dt, "acceleration")
    y = y + 1e-3 * np.random.default_rng(2).standard_normal(u.size)
    with pytest.raises(InputError, match="Nyquist|fewer than 1"):
        identify(dt * np.arange(u.size), u, SensorOutput(samples=y, kind="acceleration"), modes=1)


def test_more_modes_than_the_data_show():
    dt = 0.02
    u = np.zeros(1500)
    u[:100], u[100:200] = 1.0, -1.0
    y = simulate_output(ModalModel(b0=0.5), 1.0, [], u, dt) + 1e-4 * np.random.default_rng(3).standard_normal(1500)
    with pytest.raises(InputError) as info:
        identify(dt * np.arange(1500), u, SensorOutput(samples=y), modes=2)
    assert info.value.parameter in ("modes", "data.input") and "fewer" in str(info.value)
    # and selection finds none
    assert identify(dt * np.arange(1500), u, SensorOutput(samples=y)).n_modes == 0


def test_bad_arguments():
    t = np.arange(200) * 0.01
    u = np.sin(t)
    y = np.cos(t)
    refused("modes", "integer", time=t, u=u, outputs=SensorOutput(samples=y), modes=-1)
    refused("data.output.kind", "position", time=t, u=u, outputs=SensorOutput(samples=y, kind="jerk"))
    refused("data.output", "rigid body", time=t, u=u, outputs=SensorOutput(samples=y, rigid_weight=0.0))
