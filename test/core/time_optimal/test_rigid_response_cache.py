"""The rigid body's responses are built once per ``(b0, c)``, and ``rigid_time`` builds no dual direction.

A 3-mode replan called :func:`rigid_profile` three times (move budget,
short-move test, lower bound), each building a rigid model and its
responses: 80 of its 95 us.  The cached responses give the same profile,
bit for bit, as freshly built ones.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.simulation import modal_response
from flexmotion_ros.core.time_optimal import rigid_body


@pytest.mark.parametrize("c", [0.0, -0.3])
def test_rigid_profile_builds_no_response_when_repeated(c):
    model = ModalModel(b0=2.0, c=c, omega=(10.0, 31.0), zeta=(0.01, 0.02), b=(1.0, -0.5))
    x0 = np.array([-1.3, 0.4, 0.01, 0.0, 0.0, 0.2])
    first = rigid_body.rigid_profile(model, 5.0, x0, True)
    built = []
    real = modal_response.ModalResponse.__init__

    def counted(self, *args, **kwargs):
        built.append(1)
        real(self, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(modal_response.ModalResponse, "__init__", counted)
        again = rigid_body.rigid_profile(model, 5.0, x0 * 0.5, True)
        rigid_body.rigid_profile(model, 5.0, x0, True)
    assert not built
    # the same profile as from freshly built responses of the rigid model
    fresh = modal_response.ModalResponse(model.with_changes(omega=(), zeta=(), b=()), True)
    assert first.switch_times.size == 1
    tau1 = first.duration - first.switch_times[0]
    g = fresh.expm_B(np.array([tau1]))[0]
    nu = np.array([g[1], -g[0]])
    nu = nu if np.sign(fresh.switching(nu, np.array([0.0]))[0]) == np.sign(first.levels[-1]) else -nu
    assert np.array_equal(first.nu, nu)
    assert again.duration < first.duration


@pytest.mark.parametrize("include_position", [True, False])
@pytest.mark.parametrize("c", [0.0, -0.3])
def test_rigid_time_needs_no_dual_direction(c, include_position):
    """``rigid_time`` (the move budget and the short-move test, every plan) skips ``_rigid_nu``: same duration."""
    model = ModalModel(b0=-1.5, c=c, omega=(10.0,), zeta=(0.01,), b=(1.0,))
    x0 = np.array([0.7, -0.2, 0.01, 0.0]) if include_position else np.array([-0.2, 0.01, 0.0])
    expected = rigid_body.rigid_profile(model, 3.0, x0, include_position).duration

    def no_nu(*args):
        raise AssertionError("the dual direction was built")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rigid_body, "_rigid_nu", no_nu)
        assert rigid_body.rigid_time(model, 3.0, x0, include_position) == expected
