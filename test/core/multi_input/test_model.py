"""MultiModel: validation (one line naming the parameter), PBH controllability, normality, layout, builders."""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core import ModalModel
from flexmotion_ros.core.errors import ConfigError, ModelError
from flexmotion_ros.core.multi_input import (
    MultiModel,
    decoupled_parts,
    multi_model_from_parameters,
    multi_setup_from_parameters,
)
from flexmotion_ros.core.multi_input.builders import gantry, multi_chain, multi_two_mass

from .independent import matrices

ISSUE_YAML = {
    "model": {
        "inputs": ["trolley", "bridge"],
        "rigid_bodies": ["x", "y"],
        "b0": [0.004, 0.0, 0.0, 0.0018],
        "c": [0.0, 0.0],
        "omega": [1.85, 2.48],
        "zeta": [0.0, 0.0],
        "b": [0.0, -0.0006, -0.0025, 0.0],
    },
    "u_max": [300.0, 500.0],
}


def two_input(**kw) -> MultiModel:
    args = dict(
        inputs=("a", "b"),
        rigid_bodies=("x",),
        b0=((1.0, 1.0),),
        c=(0.0,),
        omega=(1.0, 2.0),
        zeta=(0.0, 0.0),
        b=((1.0, 0.5), (0.3, -1.0)),
    )
    args.update(kw)
    return MultiModel(**args)


def test_issue_layout_parses_row_major():
    setup = multi_setup_from_parameters(ISSUE_YAML)
    model = setup.model
    assert model.inputs == ("trolley", "bridge") and model.rigid_bodies == ("x", "y")
    assert np.array_equal(model.B0, [[0.004, 0.0], [0.0, 0.0018]])
    assert np.array_equal(model.Bm, [[0.0, -0.0006], [-0.0025, 0.0]])
    assert np.array_equal(setup.u_max, [300.0, 500.0]) and setup.sync == "time"
    # flat dotted names give the same model
    flat = {f"model.{k}": v for k, v in ISSUE_YAML["model"].items()}
    assert multi_model_from_parameters(flat) == model
    # the matrices equal an independent construction
    A, B = matrices(model)
    assert np.array_equal(model.A(), A) and np.array_equal(model.B(), B)
    # decoupled: mode 1 only by the bridge (y), mode 2 only by the trolley (x)
    parts = decoupled_parts(model)
    assert sorted(p[0] for p in parts) == [(0,), (1,)]
    assert not model.is_normal


@pytest.mark.parametrize(
    ("change", "parameter", "words"),
    [
        ({"b0": [0.004, 0.0, 0.0]}, "model.b0", "k x m = 2 x 2 = 4"),
        ({"b": [0.0, -0.0006]}, "model.b", "N x m = 2 x 2 = 4"),
        ({"c": [0.0, 0.1]}, "model.c[1]", "<= 0"),
        ({"omega": [1.85, -2.0]}, "model.omega[1]", "> 0"),
        ({"zeta": [0.0, 1.0]}, "model.zeta[1]", "[0, 1)"),
        ({"b": [0.0, -0.0006, 0.0, 0.0]}, "model.b[1]", "reached by no input"),
        ({"b0": [0.004, 0.0, 0.0, 0.0]}, "model.b0[1]", "rigid body 'y' is reached by no input"),
        ({"b0": [0.004, 0.002, 0.002, 0.001]}, "model.b0", "not controllable"),
        ({"inputs": ["trolley", "trolley"]}, "model.inputs", "unique"),
    ],
)
def test_bad_models_are_refused_naming_the_parameter(change, parameter, words):
    params = {"model": {**ISSUE_YAML["model"], **change}, "u_max": [1.0, 1.0]}
    with pytest.raises(ModelError) as err:
        multi_model_from_parameters(params)
    assert err.value.parameter == parameter
    assert words in str(err.value) and "\n" not in str(err.value)


def test_bad_bounds_sync_and_weights_name_the_parameter():
    cases = (
        ({"u_max": [1.0, 2.0, 3.0]}, "u_max"),
        ({"u_max": [1.0, -2.0]}, "u_max[1]"),
        ({"sync": "both"}, "sync"),
        ({"fuel_weights": [1.0, 0.0]}, "fuel_weights[1]"),
    )
    for change, parameter in cases:
        params = {**ISSUE_YAML, **change}
        with pytest.raises(ConfigError) as err:
            multi_setup_from_parameters(params)
        assert err.value.parameter == parameter


def test_repeated_frequencies_accepted_when_the_inputs_together_control_them():
    model = two_input(omega=(2.0, 2.0), zeta=(0.01, 0.01), b=((1.0, 0.0), (0.0, 1.0)))
    assert model.mode_groups() == [[0, 1]]
    # PBH with all inputs, numerically: rank [A - lambda I, B] = n at every eigenvalue
    A, B = model.A(), model.B()
    for lam in np.linalg.eigvals(A):
        assert np.linalg.matrix_rank(np.hstack([A - lam * np.eye(A.shape[0]), B]), tol=1e-9) == A.shape[0]
    assert all(r is not None for r in model.normality())  # neither input alone controls both
    with pytest.raises(ModelError) as err:
        two_input(omega=(2.0, 2.0), zeta=(0.01, 0.01), b=((1.0, 2.0), (0.5, 1.0)))
    assert err.value.parameter == "model.omega[1]"
    assert "mode_1" in err.value.reason and "mode_2" in err.value.reason and "['a', 'b']" in err.value.reason
    # the refusal agrees with the numerical PBH test
    bad = np.array([[1.0, 2.0], [0.5, 1.0]])
    A2 = np.zeros((6, 6))
    A2[0, 1] = 1
    for r in (2, 4):
        A2[r, r + 1], A2[r + 1, r], A2[r + 1, r + 1] = 1, -4, -0.04
    B2 = np.zeros((6, 2))
    B2[1] = [1, 1]
    B2[3], B2[5] = bad
    lam = np.linalg.eigvals(A2[2:4, 2:4])[0]
    assert np.linalg.matrix_rank(np.hstack([A2 - lam * np.eye(6), B2]), tol=1e-9) < 6


def test_normality_per_input():
    assert two_input().is_normal
    reasons = two_input(b=((1.0, 0.0), (0.3, -1.0))).normality()
    assert reasons[0] is None and "mode_1" in reasons[1]


def test_from_modal_is_the_single_input_model():
    mm = ModalModel(b0=0.5, c=-0.1, omega=[1.4, 3.0], zeta=[0.01, 0.02], b=[1.0, -0.4])
    M = MultiModel.from_modal(mm)
    assert np.allclose(M.A(), mm.A()) and np.allclose(M.B()[:, 0], mm.B())
    assert M.is_normal and M.m == M.k == 1


def test_gantry_builder_physics_and_map():
    g = gantry(10.0, 40.0, 5.0, 2.0, g=9.81, trolley_force=30.0, bridge_force=50.0)
    M = g.model
    assert M.inputs == ("trolley", "bridge") and M.rigid_bodies == ("x", "y")
    assert np.isclose(M.omega[0], np.sqrt(9.81 * 15 / (10 * 2))) and np.isclose(
        M.omega[1], np.sqrt(9.81 * 55 / (50 * 2))
    )
    # static check of the map: payload offset s_x = 1 m, centre of mass at 0 -> trolley and payload 1 m apart,
    # centre of mass m_t x_t + m_p x_p = 0
    x = np.zeros(M.n_states)
    x[4] = 1.0
    y = g.physical_positions(x)
    assert np.isclose(y[1] - y[0], 1.0) and np.isclose(10 * y[0] + 5 * y[1], 0.0)
    assert np.array_equal(g.u_max, [30.0, 50.0])
    with pytest.raises(ModelError) as err:
        gantry(10.0, 40.0, 5.0, -2.0)
    assert err.value.parameter == "rope_length"


def test_chain_with_actuated_masses_and_two_mass():
    c = multi_chain([1, 1, 1, 1], [100, 100, 100], actuated=(0, 3), u_max=[5, 3])
    assert c.model.inputs == ("f0", "f3") and c.model.is_normal
    # the single-input chain (existing builder) gives the same column for a force at mass 0
    from flexmotion_ros.core import chain

    single = chain([1, 1, 1, 1], [100, 100, 100], force_on=0).model
    assert np.allclose(c.model.Bm[:, 0], single.b) and np.allclose(c.model.omega, single.omega)
    # a force at the middle of a symmetric 3-mass chain does not reach the antisymmetric mode: not normal
    mid = multi_chain([1, 1, 1], [50, 50], actuated=(0, 1))
    assert mid.model.Bm[0, 1] == 0.0 and mid.model.normality()[1] is not None
    tm = multi_two_mass(1.0, 2.0, 3.0, actuated=(0, 1))
    assert np.isclose(tm.model.omega[0], np.sqrt(3.0 * (1 + 1 / 2)))
    with pytest.raises(ModelError) as err:
        multi_chain([1, 1], [10], actuated=(0, 2))
    assert err.value.parameter == "actuated"


def test_the_issue_parameter_file_as_yaml():
    import yaml

    text = """
/**:
  ros__parameters:
    model:
      inputs: [trolley, bridge]          # m actuated joints
      rigid_bodies: [x, y]               # k rigid-body coordinates
      b0: [0.004, 0.0, 0.0, 0.0018]      # k x m, row-major (1/kg)
      c: [0.0, 0.0]
      omega: [1.85, 2.48]                # rad/s, any order; repeated values allowed when controllable
      zeta: [0.0, 0.0]
      b: [0.0, -0.0006, -0.0025, 0.0]    # N x m, row-major
    u_max: [300.0, 500.0]                # N, one per input
"""
    params = yaml.safe_load(text)
    from flexmotion_ros.core.multi_input import is_multi_input

    assert is_multi_input(params)
    setup = multi_setup_from_parameters(params)
    assert setup.model == multi_model_from_parameters(ISSUE_YAML)
    assert np.array_equal(setup.u_max, [300.0, 500.0])
