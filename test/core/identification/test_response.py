"""Unit responses of the estimator (discrete transfer functions run by ``lfilter``) against the
independent whole-model matrix-exponential propagation of ``truth.simulate_output``, and their
complex-step derivatives against central differences of that simulator."""

import numpy as np
import pytest

from flexmotion_ros.core.identification.response import (
    OutputKind,
    unit_response,
    unit_response_and_derivatives,
    zoh_filter,
)
from flexmotion_ros.core.model.modal_model import ModalModel

from .truth import simulate_output

DT = 0.01
U = np.random.default_rng(3).standard_normal(800)


def rigid_truth(c, kind, u=U):
    return simulate_output(ModalModel(b0=1.0, c=c), 1.0, [], u, DT, kind)


def mode_truth(w, z, kind, u=U):
    # the rigid body read with weight 0, the mode with weight 1 and input gain 1
    return simulate_output(ModalModel(b0=1.0, omega=(w,), zeta=(z,), b=(1.0,)), 0.0, [1.0], u, DT, kind)


@pytest.mark.parametrize("kind", list(OutputKind))
@pytest.mark.parametrize("c", [0.0, -0.3])
def test_rigid_unit_response_is_the_exact_zoh_response(kind, c):
    ref = rigid_truth(c, kind)
    got = unit_response(kind, True, DT, U, c)
    assert np.max(np.abs(got - ref)) <= 1e-11 * np.max(np.abs(ref))


@pytest.mark.parametrize("kind", list(OutputKind))
@pytest.mark.parametrize("w,z", [(2.3, 0.0), (7.0, 0.05), (40.0, 0.4)])
def test_mode_unit_response_is_the_exact_zoh_response(kind, w, z):
    ref = mode_truth(w, z, kind)
    got = unit_response(kind, False, DT, U, w, z)
    assert np.max(np.abs(got - ref)) <= 1e-11 * np.max(np.abs(ref))


def test_acceleration_has_direct_feedthrough_and_position_velocity_do_not():
    """Under ZOH ``q'' = u - 2 zeta omega q' - omega^2 q`` jumps with the input: the sample read after
    ``u_0`` is applied is ``u_0``; position and velocity need a sample to respond."""
    for rigid, params in ((True, (0.0,)), (False, (3.0, 0.02))):
        b_acc, _ = zoh_filter(OutputKind.ACCELERATION, rigid, DT, *params)
        assert b_acc[0] == 1.0
        for kind in (OutputKind.POSITION, OutputKind.VELOCITY):
            b, _ = zoh_filter(kind, rigid, DT, *params)
            assert b[0] == 0.0
    u = np.zeros(10)
    u[0] = 2.5
    assert unit_response(OutputKind.ACCELERATION, False, DT, u, 3.0, 0.02)[0] == pytest.approx(2.5)
    assert unit_response(OutputKind.POSITION, False, DT, u, 3.0, 0.02)[0] == 0.0


@pytest.mark.parametrize("kind", list(OutputKind))
def test_derivatives_match_central_differences_of_the_independent_simulator(kind):
    c, w, z = -0.2, 4.1, 0.03
    _, (dc,) = unit_response_and_derivatives(kind, True, DT, U, (c,))
    h = 1e-6
    fd = (rigid_truth(c + h, kind) - rigid_truth(c - h, kind)) / (2 * h)
    assert np.max(np.abs(dc - fd)) <= 1e-6 * np.max(np.abs(fd))
    _, (dw, dz) = unit_response_and_derivatives(kind, False, DT, U, (w, z))
    fdw = (mode_truth(w + h, z, kind) - mode_truth(w - h, z, kind)) / (2 * h)
    fdz = (mode_truth(w, z + h, kind) - mode_truth(w, z - h, kind)) / (2 * h)
    assert np.max(np.abs(dw - fdw)) <= 1e-6 * np.max(np.abs(fdw))
    assert np.max(np.abs(dz - fdz)) <= 1e-6 * np.max(np.abs(fdz))
