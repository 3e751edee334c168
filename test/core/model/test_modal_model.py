"""ModalModel: validation (named parameter, allowed range), A/B structure, modal form (eqs. 2.6-2.7)."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from flexmotion_ros.core import FlexmotionError, ModalModel, ModelError, rest_to_rest
from flexmotion_ros.core.model.boundary import MoveProblem

GOOD = {
    "b0": 0.5,
    "c": -0.1,
    "omega": (1.5, 4.0),
    "zeta": (0.02, 0.1),
    "b": (1.0, -0.7),
}


def model(**changes):
    params = dict(GOOD)
    params.update(changes)
    return ModalModel(**params)


# --------------------------------------------------------------- validation
NON_FINITE = [math.nan, math.inf, -math.inf]


@pytest.mark.parametrize("bad", NON_FINITE + ["abc", None])
@pytest.mark.parametrize(
    "field, parameter, build",
    [
        ("b0", "model.b0", lambda v: model(b0=v)),
        ("c", "model.c", lambda v: model(c=v)),
        ("omega", "model.omega[1]", lambda v: model(omega=(1.5, v))),
        ("zeta", "model.zeta[0]", lambda v: model(zeta=(v, 0.1))),
        ("b", "model.b[1]", lambda v: model(b=(1.0, v))),
    ],
)
def test_every_parameter_must_be_finite(field, parameter, build, bad):
    with pytest.raises(ModelError) as exc:
        build(bad)
    assert exc.value.parameter == parameter
    assert "finite" in exc.value.reason
    assert str(exc.value).startswith(parameter)


@pytest.mark.parametrize("w", [0.0, -1.0, -1e-300])
def test_omega_must_be_positive(w):
    with pytest.raises(ModelError) as exc:
        model(omega=(1.5, w))
    assert exc.value.parameter == "model.omega[1]"
    assert "> 0" in exc.value.reason and "rad/s" in exc.value.reason


@pytest.mark.parametrize("z", [-1e-12, -0.1, 1.0, 1.5])
def test_zeta_must_be_in_unit_interval(z):
    with pytest.raises(ModelError) as exc:
        model(zeta=(z, 0.1))
    assert exc.value.parameter == "model.zeta[0]"
    assert "[0, 1)" in exc.value.reason


def test_zeta_boundaries_accepted():
    assert model(zeta=(0.0, 0.999999)).zeta == (0.0, 0.999999)


def test_b0_must_be_nonzero():
    with pytest.raises(ModelError) as exc:
        model(b0=0.0)
    assert exc.value.parameter == "model.b0"
    assert "non-zero" in exc.value.reason and "uncontrollable" in exc.value.reason


@pytest.mark.parametrize("b0", [-2.0, 1e-6, 1e6])
def test_b0_of_either_sign(b0):
    assert model(b0=b0).b0 == b0


@pytest.mark.parametrize("c", [1e-12, 0.5])
def test_c_must_be_nonpositive(c):
    with pytest.raises(ModelError) as exc:
        model(c=c)
    assert exc.value.parameter == "model.c"
    assert "<= 0" in exc.value.reason


def test_c_zero_and_negative_accepted():
    assert model(c=0.0).c == 0.0
    assert model(c=-3.0).c == -3.0


@pytest.mark.parametrize("i", [0, 1])
def test_zero_modal_gain_refused_as_uncontrollable(i):
    b = [1.0, -0.7]
    b[i] = 0.0
    with pytest.raises(ModelError) as exc:
        model(b=tuple(b))
    assert exc.value.parameter == f"model.b[{i}]"
    assert "uncontrollable" in exc.value.reason
    assert "non-zero" in exc.value.reason


@pytest.mark.parametrize("second", [1.5, 1.5 * (1 + 1e-12)])
def test_repeated_frequencies_refused(second):
    with pytest.raises(ModelError) as exc:
        model(omega=(1.5, second))
    assert exc.value.parameter == "model.omega[1]"
    assert "not controllable" in exc.value.reason
    assert "model.omega[0]" in exc.value.reason


def test_repeated_frequencies_refused_whatever_the_order():
    with pytest.raises(ModelError) as exc:
        ModalModel(b0=1.0, omega=(2.0, 5.0, 2.0), zeta=(0, 0, 0), b=(1, 1, 1))
    assert exc.value.parameter == "model.omega[2]"


def test_close_but_distinct_frequencies_accepted():
    m = model(omega=(1.5, 1.5 * (1 + 1e-6)))
    assert m.n_modes == 2


def test_lengths_must_agree():
    with pytest.raises(ModelError) as exc:
        model(zeta=(0.02,))
    assert "omega" in exc.value.parameter and "same length" in exc.value.reason


def test_model_error_is_a_flexmotion_error_and_a_value_error():
    with pytest.raises(FlexmotionError):
        model(b0=0.0)
    with pytest.raises(ValueError):
        model(b0=0.0)


@pytest.mark.parametrize("u_max", [0.0, -1.0, math.nan, math.inf])
def test_u_max_must_be_positive_and_finite(u_max):
    with pytest.raises(FlexmotionError) as exc:
        rest_to_rest(model(), u_max, 1.0)
    assert exc.value.parameter == "u_max"


@pytest.mark.parametrize("goal", [math.nan, math.inf])
def test_goal_must_be_finite(goal):
    with pytest.raises(FlexmotionError) as exc:
        rest_to_rest(model(), 1.0, goal)
    assert exc.value.parameter == "goal"
    assert "finite" in exc.value.reason


def test_initial_state_must_match_and_be_finite():
    m = model()
    with pytest.raises(FlexmotionError) as exc:
        MoveProblem(m, 1.0, np.zeros(3), 0.0)
    assert exc.value.parameter == "initial_state"
    x = np.zeros(m.n_states)
    x[3] = math.nan
    with pytest.raises(FlexmotionError) as exc:
        MoveProblem(m, 1.0, x, 0.0)
    assert exc.value.parameter == "initial_state"
    assert "mode_1_dot" in exc.value.reason


def test_with_changes_revalidates():
    m = model()
    with pytest.raises(ModelError) as exc:
        m.with_changes(b0=0.0)
    assert exc.value.parameter == "model.b0"
    assert m.with_changes(omega=(2.0,), zeta=(0.0,), b=(1.0,)).n_modes == 1


# ------------------------------------------------------------- structure
def test_A_B_structure():
    m = model()
    A, B = m.A(), m.B()
    assert A.shape == (6, 6) and B.shape == (6,)
    expected = np.zeros((6, 6))
    expected[0, 1] = 1.0
    expected[1, 1] = m.c
    for i, (w, z) in enumerate(zip(m.omega, m.zeta)):
        k = 2 + 2 * i
        expected[k, k + 1] = 1.0
        expected[k + 1, k] = -w * w
        expected[k + 1, k + 1] = -2.0 * z * w
    np.testing.assert_array_equal(A, expected)
    np.testing.assert_array_equal(B, [0.0, 0.5, 0.0, 1.0, 0.0, -0.7])


def test_A_eigenvalues_are_the_modal_poles():
    m = model()
    ev = np.sort_complex(np.linalg.eigvals(m.A()))
    poles = [0.0, m.c]
    for w, z in zip(m.omega, m.zeta):
        wd = w * math.sqrt(1 - z * z)
        poles += [complex(-z * w, wd), complex(-z * w, -wd)]
    np.testing.assert_allclose(ev, np.sort_complex(np.array(poles, complex)), atol=1e-12)


def test_sizes_names_rest_and_natural_distance():
    m = model()
    assert (m.n_modes, m.n_states) == (2, 6)
    assert m.state_names() == ["p", "v", "mode_1", "mode_1_dot", "mode_2", "mode_2_dot"]
    np.testing.assert_array_equal(m.rest_state(2.5), [2.5, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(m.omega_d, [1.5 * math.sqrt(1 - 0.02**2), 4.0 * math.sqrt(1 - 0.01)], rtol=1e-15)
    assert m.natural_distance(2.0) == pytest.approx(0.5 * 2.0 / 1.5**2, rel=1e-15)
    rigid = ModalModel(b0=-2.0)
    assert (rigid.n_modes, rigid.n_states, rigid.natural_distance(3.0)) == (0, 2, 1.0)
    np.testing.assert_array_equal(rigid.A(), [[0, 1], [0, 0]])
    np.testing.assert_array_equal(rigid.B(), [0, -2.0])


def test_to_dict_round_trip():
    m = model()
    assert ModalModel(**m.to_dict()) == m


# ------------------------------------------------------------ modal form
def test_modal_form_eqs_2_6_2_7():
    m = model(zeta=(0.0, 0.3))
    At, Bt, M = m.modal_form()
    # M from eq. 2.6, built here independently
    M_ref = np.eye(m.n_states)
    for i, (w, z) in enumerate(zip(m.omega, m.zeta)):
        wd = w * math.sqrt(1 - z * z)
        k = 2 + 2 * i
        M_ref[k : k + 2, k : k + 2] = [[1 / wd, 0.0], [-z / math.sqrt(1 - z * z), 1.0]]
    np.testing.assert_allclose(M, M_ref, rtol=1e-15, atol=0)
    # eq. 2.7: each mode block is [[-zeta w, w_d], [-w_d, -zeta w]]; rigid block unchanged
    np.testing.assert_allclose(At[:2, :2], m.A()[:2, :2], atol=1e-15)
    for i, (w, z) in enumerate(zip(m.omega, m.zeta)):
        wd = w * math.sqrt(1 - z * z)
        k = 2 + 2 * i
        np.testing.assert_allclose(
            At[k : k + 2, k : k + 2],
            [[-z * w, wd], [-wd, -z * w]],
            rtol=1e-12,
            atol=1e-12,
        )
    off = At.copy()
    for k in range(0, m.n_states, 2):
        off[k : k + 2, k : k + 2] = 0.0
    assert np.max(np.abs(off)) == 0.0
    # similarity: x = M x~, so M x~' = A M x~ and the same trajectories
    np.testing.assert_allclose(M @ At, m.A() @ M, atol=1e-12)
    np.testing.assert_allclose(M @ Bt, m.B(), atol=1e-15)
    for t in (0.3, 2.0, 7.0):
        np.testing.assert_allclose(M @ expm(At * t) @ np.linalg.inv(M), expm(m.A() * t), atol=1e-11)
