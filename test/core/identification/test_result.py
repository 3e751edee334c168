"""The result a node or the command line gets: a planning model, plain values for JSON, what is and
is not identifiable, and the claim that rest-to-rest plans need only b0, c, omega, zeta."""

import json
import math

import numpy as np
import pytest

from flexmotion_ros.core.identification import SensorOutput, identify
from flexmotion_ros.core.identification.result import Estimate
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal

from .truth import crane_case, noise_for_snr, simulate_output, two_mass_case


@pytest.fixture(scope="module")
def result():
    model, a0, a, u, dt, kind = two_mass_case()
    y = simulate_output(model, a0, a, u, dt, kind)
    y = y + noise_for_snr(y, 30.0) * np.random.default_rng(1).standard_normal(u.size)
    return identify(dt * np.arange(u.size), u, SensorOutput(samples=y, name="x2"), modes=1)


def test_to_dict_is_json_with_the_fields_of_the_issue(result):
    d = json.loads(json.dumps(result.to_dict()))
    for key in ("b0", "c", "modes", "noise_std", "fit_rms", "samples", "solve_time_s"):
        assert key in d
    mode = d["modes"][0]
    for key in ("omega", "zeta", "omega_interval", "zeta_interval"):
        assert key in mode
    lo, hi = mode["omega_interval"]
    assert lo < mode["omega"] < hi and hi - lo == pytest.approx(2 * 1.959963984540054 * mode["omega_std_error"])
    assert d["samples"] == 1500 and d["outputs"][0]["name"] == "x2"
    assert d["not_identifiable"] and "b_i and a_ji separately" in d["not_identifiable"][0]
    assert "only b0, c, omega and zeta" in d["planning_note"]


def test_to_model_is_a_valid_planning_model(result):
    m = result.to_model()
    assert isinstance(m, ModalModel)
    assert m.b0 == result.b0.value and m.omega[0] == result.modes[0].omega.value
    assert m.b == (result.modes[0].gains[0].value,)
    assert m.c <= 0.0 and 0.0 <= m.zeta[0] < 1.0
    assert result.to_model(b=[2.0], names=["swing"]).b == (2.0,)


def test_to_model_clips_a_slightly_unphysical_estimate():
    model, a0, a, u, dt, kind = crane_case()
    model = model.with_changes(c=0.0, zeta=(0.0,))
    y = simulate_output(model, a0, a, u, dt, kind)
    y = y + noise_for_snr(y, 20.0) * np.random.default_rng(4).standard_normal(u.size)
    r = identify(dt * np.arange(u.size), u, SensorOutput(samples=y), modes=1)
    m = r.to_model()
    assert m.c == min(r.c.value, 0.0) and m.zeta[0] == max(r.modes[0].zeta.value, 0.0)
    # the interval, not the clip, is what the data say: it contains the true zero
    assert r.c.contains(0.0) and r.modes[0].zeta.contains(0.0)


def test_rest_to_rest_plans_do_not_depend_on_the_modal_gains():
    """The claim in PLANNING_NOTE, checked with the planner: any b (scale and sign) gives the same move."""
    base = ModalModel(b0=0.5, c=-0.02, omega=(1.3, 4.1), zeta=(0.02, 0.05), b=(1.0, 1.0))
    ref = plan_time_optimal(rest_to_rest(base, 1.0, 1.0))
    for b in ((-3.7, 0.2), (0.01, -50.0)):
        other = plan_time_optimal(rest_to_rest(base.with_changes(b=b), 1.0, 1.0))
        assert other.duration == pytest.approx(ref.duration, rel=1e-9)
        assert np.allclose(other.switch_times, ref.switch_times, rtol=1e-8)


def test_estimate_interval():
    e = Estimate(value=2.0, std_error=0.5)
    assert e.interval == pytest.approx((2.0 - 0.98, 2.0 + 0.98), rel=1e-3)
    assert e.contains(2.9) and not e.contains(3.0)
    assert math.isinf(Estimate(value=1.0, std_error=math.inf).interval[1])
