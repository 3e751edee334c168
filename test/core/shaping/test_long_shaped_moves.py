"""Shaped commands of very long moves keep every step of the convolution (issue 15, um_zvd).

Fuzz seed 15, cases 257, 362 and 886 (8 modes, UM-ZVD: 390,625 impulses of size 1, the rigid
level lowered to 1-8 % of ``u_max``, commands of 81,000-407,000 s) were refused with "simulated
residual vibration disagrees with the impulse formula".  The impulse formula was right: the
command as stored had 2e-8 to 3e-7 of a step of residual vibration (the same sum in extended
precision agreed), because :func:`shape` merged steps closer than ``1e-12 T`` (0.1-0.4 us
there); the simulation, of the convolution by its factors, had 1e-17.  The residual vibration
here is checked by the tests' own sum of the modes' exact step responses in extended precision.
"""

import numpy as np

from flexmotion_ros.core.model.boundary import MoveProblem
from flexmotion_ros.core.model.modal_model import ModalModel
from flexmotion_ros.core.shaping.shaped_profile import plan_shaped, shape
from flexmotion_ros.core.shaping.shaper import Shaper
from flexmotion_ros.core.shaping.shapers import design
from flexmotion_ros.core.simulation.exact import PiecewiseConstant

# fuzz case 886: 8 modes at rest, c = -0.82, a 1,829-unit move; UM-ZVD lowers the level to 0.9 %
CASE_886 = MoveProblem(
    ModalModel(
        b0=0.28402477722884995,
        c=-0.8220741535886708,
        omega=(0.8021089356171835, 1.0340472786905914, 1.9947285381057045, 4.041341253575099)
        + (6.426802856898834, 14.960961671438941, 42.55259326582425, 56.620119038738814),
        zeta=(0.16899377784298092, 0.17577160678667367, 0.2694028022285252, 0.052083654501423333)
        + (0.0658176690280765, 0.21789365907858338, 0.03131568365924113, 0.20877136982370745),
        b=(1.9670997168683177, 1.1049105417946101, -1.4690430578647808, 0.65425712355958)
        + (1.4672590526324407, -0.4483897637434523, 0.918156512537509, -0.33154446976746554),
    ),
    7.296207354987858,
    [0.0] * 18,
    -1828.667585896118,
)


def _residual_of_steps(command: PiecewiseConstant, omega, zeta, u_ref: float) -> np.ndarray:
    """Each mode's residual vibration (fraction of a step of ``u_ref``) from the command's own steps.

    ``|sum_k J_k e^{(-zeta w + i w_d) (T - t_k)}| / u_ref`` over the jumps ``J_k`` at ``t_k``: the
    free vibration the steps leave at the end ``T`` (exact for a piecewise-constant command),
    summed in extended precision so that its own rounding stays far below the tolerance.
    """
    levels = np.concatenate([[0.0], command.levels, [0.0]])
    t = command.breaks.astype(np.longdouble)
    jump = np.diff(levels).astype(np.longdouble) / np.longdouble(u_ref)
    age = t[-1] - t
    out = []
    for w, z in zip(omega, zeta):
        w, z = np.longdouble(w), np.longdouble(z)
        wd = w * np.sqrt(np.longdouble(1.0) - z * z)
        decay = np.exp(-z * w * age)
        out.append(float(np.hypot(np.sum(jump * decay * np.cos(wd * age)), np.sum(jump * decay * np.sin(wd * age)))))
    return np.array(out)


def test_shape_keeps_steps_closer_than_a_millionth_of_a_microsecond_per_second_of_move():
    """Two copies 30 ns apart on a 100,000 s step: both steps stay (1e-12 T = 100 ns merged them)."""
    step = PiecewiseConstant(np.array([0.0, 1e5]), np.array([1.0]))
    shaper = Shaper("pair", np.array([0.0, 3e-8]), np.array([0.5, 0.5]), (1.0,), (0.0,))
    shaped = shape(step, shaper)
    assert np.allclose(shaped.breaks[:2], [0.0, 3e-8], rtol=0.0, atol=1e-15)
    assert np.allclose(shaped.levels, [0.5, 1.0, 0.5])
    # the integral (the rigid body's impulse) is the step's: nothing lost in the merge
    assert np.isclose(np.sum(shaped.levels * np.diff(shaped.breaks)), 1e5, rtol=1e-15)


def test_an_8_mode_um_zvd_move_of_81000_s_cancels_every_mode():
    """Case 886 plans; its command's own steps leave at most 1e-8 of a step on every mode."""
    model = CASE_886.model
    shaper = design("um_zvd", model.omega, model.zeta, 0.05, 0.75, "convolve")
    profile = plan_shaped(CASE_886, shaper, "um_zvd")
    command = profile.command
    assert command.duration > 8e4 and command.levels.size > 1_000_000
    assert np.max(np.abs(command.levels)) <= CASE_886.u_max
    vib = _residual_of_steps(command, model.omega, model.zeta, CASE_886.u_max)
    assert np.all(vib <= 1e-8), vib  # before: 4.5e-8 on mode 4 (4.04 rad/s)
