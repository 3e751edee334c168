"""Identification records without ROS: pairing readings with commands, the settings, the update rule.

The hidden-truth test simulates a lockstep crane (exact ZOH, white noise, known truth), logs what the
stream would send and what the plant would publish, and fits through the same functions the planner uses.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flexmotion_ros.core.errors import ConfigError, InputError
from flexmotion_ros.core.identification.excitation import design_excitation
from flexmotion_ros.core.model.builders import crane_acceleration
from flexmotion_ros.core.model.measurement import MeasurementMap, builder_map
from flexmotion_ros.core.simulation.exact import simulate_samples
from flexmotion_ros.execution.learning import (
    IdentificationSettings,
    fit_record,
    identification_settings,
    model_update,
)
from flexmotion_ros.execution.records import SignalLog, paired_record

DT = 0.005
DT_NS = 5_000_000
T0 = 1_700_000_000_000_000_000


def lockstep_logs(u, y, jitter_ns=None, late_burst: slice | None = None):
    """The stream's sent log (time just before publishing) and the plant's readings (stamped with the send time)."""
    n = len(u)
    t = T0 + DT_NS * np.arange(n) + (np.zeros(n, int) if jitter_ns is None else jitter_ns)
    if late_burst is not None:  # a stream that fell behind sends these back to back
        t[late_burst] = t[late_burst.start] + 20_000 * np.arange(late_burst.stop - late_burst.start)
    sent, readings = SignalLog(4096, 1), SignalLog(4096, np.shape(y)[1])
    for k in range(n):
        sent.append(int(t[k]), (u[k],))
        readings.append(int(t[k]) + 3_000, y[k])  # DDS takes its source timestamp a few us later
    return sent, readings


def test_lockstep_pairing_is_one_to_one_even_through_a_late_burst():
    rng = np.random.default_rng(1)
    u = rng.uniform(-1, 1, 300)
    y = np.column_stack([u * 2.0, np.arange(300.0)])
    sent, readings = lockstep_logs(u, y, jitter_ns=rng.integers(0, 800_000, 300), late_burst=slice(100, 140))
    rec = paired_record(sent, readings, 10, 250, None, DT)
    assert rec.exact and rec.samples == 241
    np.testing.assert_array_equal(rec.u, u[10:251])
    np.testing.assert_array_equal(rec.y[:, 1], np.arange(10.0, 251.0))  # reading k after command k


def test_a_lost_reading_is_refused_with_where():
    u = np.zeros(50)
    y = np.arange(50.0)[:, None]
    sent, _ = lockstep_logs(u, y)
    readings = SignalLog(100, 1)
    for k in range(50):
        if k != 20:
            readings.append(T0 + DT_NS * k + 3_000, y[k])
    with pytest.raises(InputError) as err:
        paired_record(sent, readings, 0, 49, None, DT)
    assert err.value.parameter == "measurements" and "1 of 50 commands have no reading (first: sample 20" in str(
        err.value
    )
    with pytest.raises(InputError, match="no reading received since the first command"):
        paired_record(sent, SignalLog(10, 1), 0, 49, None, DT)


def test_real_time_readings_pair_with_the_command_held_then():
    u = np.repeat([1.0, -1.0, 0.5, 0.0], 25)
    sent = SignalLog(200, 1)
    for k in range(100):
        sent.append(T0 + DT_NS * k, (u[k],))
    readings = SignalLog(200, 1)
    for k in range(100):  # the plant's own ticks, 2.3 ms after each command
        readings.append(T0 + DT_NS * k + 2_300_000, (float(k),))
    rec = paired_record(sent, readings, 0, 99, T0 + DT_NS * 100, DT)
    assert not rec.exact
    np.testing.assert_array_equal(rec.u, u)


@pytest.mark.parametrize(
    ("values", "name"),
    [
        ({"identification.band": [5.0, 1.0]}, "identification.band"),
        ({"identification.band": [1.0]}, "identification.band"),
        ({"identification.modes": 9}, "identification.modes"),
        ({"identification.duration_s": -1.0}, "identification.duration_s"),
        ({"identification.max_omega_interval": 0.0}, "identification.max_omega_interval"),
        ({"identification.ringdown_s": math.nan}, "identification.ringdown_s"),
    ],
)
def test_bad_settings_are_refused_naming_the_parameter(values, name):
    with pytest.raises(ConfigError) as err:
        identification_settings(values)
    assert err.value.parameter == name


def test_hidden_truth_lockstep_crane_is_identified_and_only_contradicted_parameters_change():
    built = crane_acceleration(9.81 / 100.0)  # the file: 10 rad/s, zeta 0
    mmap = builder_map(built)
    believed = built.model
    true = believed.with_changes(omega=(11.2,), zeta=(0.03,))
    exc = design_excitation(believed, 50.0, 200.0, (4.0, 20.0), duration=2.0, start=0.0)
    u = np.append(exc.commands, 0.0)  # and the hold
    x = simulate_samples(true, true.rest_state(), u, DT)[:-1]
    C, D = mmap.for_model(true)
    noise = np.array([1e-4, 1e-4, 1e-3])
    y = x @ C.T + D * u[:, None] + noise * np.random.default_rng(2).standard_normal(x.shape[:1] + (3,))
    sent, readings = lockstep_logs(u, y, jitter_ns=np.random.default_rng(3).integers(0, 1_000_000, u.size))
    rec = paired_record(sent, readings, 0, u.size - 1, None, DT)
    result = fit_record(rec, mmap, believed, 1, 50.0)
    m = result.modes[0]
    assert m.omega.contains(11.2) and m.zeta.contains(0.03), (m.omega, m.zeta)
    update = model_update(believed, result, IdentificationSettings())
    assert update.confident and update.model.omega[0] == m.omega.value and update.model.zeta[0] == m.zeta.value
    assert update.model.b0 == believed.b0  # inside its interval: kept, not replaced by the noisy estimate
    assert [c.split()[0] for c in update.changes] == ["omega[0]", "zeta[0]"]
    # wide intervals (a demanding threshold): not confident, says why
    strict = model_update(believed, result, IdentificationSettings(max_omega_interval=1e-9))
    assert not strict.confident and "identification.max_omega_interval" in strict.reason
    # a record with no channel on the mode cannot identify it
    cart_only = MeasurementMap(names=("cart",), map=np.array([[1.0, 0.0]]), kinds=mmap.kinds[:1])
    with pytest.raises(InputError, match="measurement.map"):
        fit_record(rec, cart_only, believed, 1, 50.0)
