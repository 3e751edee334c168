"""The identification figure (``plots/identification.py``), read back: command, measured and fitted
response, residual with the noise band, spectrum with each mode's line and 95 % interval; every axis
labelled with its unit."""

import numpy as np
from core.identification.truth import beam_case, noise_for_snr, simulate_output

from flexmotion_ros.core.identification import SensorOutput, identify
from flexmotion_ros.plots.identification import amplitude_spectrum, plot_identification


def test_the_figure_shows_fit_residual_and_the_modes_with_intervals(tmp_path):
    model, a0, a, u, dt, kind = beam_case()
    y = simulate_output(model, a0, a, u, dt, kind)
    y = y + noise_for_snr(y, 30.0) * np.random.default_rng(0).standard_normal(u.size)
    t = dt * np.arange(u.size)
    outputs = [SensorOutput(samples=y, kind=kind, name="tip")]
    result = identify(t, u, outputs, modes=3)
    path = tmp_path / "fit.png"
    fig = plot_identification(t, u, outputs, result, str(path))
    assert path.stat().st_size > 20_000
    ax_u, ax_y, ax_r, ax_s = fig.axes
    assert ax_u.get_ylabel() == "command (N)" and ax_u.get_xlabel() == "time (s)"
    assert ax_y.get_ylabel() == "acceleration (m/s^2)"
    assert ax_r.get_ylabel() == "residual (m/s^2)"
    assert ax_s.get_xlabel() == "frequency (rad/s)" and ax_s.get_ylabel() == "amplitude (m/s^2)"
    labels = [ln.get_label() for ln in ax_y.get_lines()]
    assert labels[0] == "measured tip" and labels[1].startswith("fitted (3 mode(s))")
    assert np.allclose(ax_y.get_lines()[1].get_ydata(), result.fitted[0])
    # one dashed line at each identified frequency, and one shaded 95 % interval around it
    mode_lines = [ln for ln in ax_s.get_lines() if ln.get_label().startswith("mode ")]
    assert [ln.get_xdata()[0] for ln in mode_lines] == [m.omega.value for m in result.modes]
    spans = [p for p in ax_s.patches]
    assert len(spans) == 3
    for span, m in zip(spans, result.modes):
        x0, x1 = span.get_x(), span.get_x() + span.get_width()
        assert np.allclose([x0, x1], m.omega.interval)


def test_amplitude_spectrum_of_a_sinusoid():
    dt = 0.01
    t = dt * np.arange(1000)
    w, amp = amplitude_spectrum(0.3 * np.cos(2 * np.pi * 5.0 * t), dt)
    assert np.isclose(w[np.argmax(amp)], np.pi * 10.0) and np.isclose(np.max(amp), 0.3)
