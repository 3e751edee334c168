"""Structure design: known answers derived independently, certification, bounds, files, CLI.

Independent reference (no planner involved)
-------------------------------------------
For ``two_mass(1, 1, k)``: ``p'' = u/2``, ``q'' = -2k q + u``.  With
``s = sqrt(k) t``, ``P = k p``, ``Q = k q`` this becomes ``P'' = u/2``,
``Q'' = -2 Q + u`` (the Wie-Bernstein system, k = 1) and a move by ``gamma``
becomes a move by ``k gamma``.  So the stiffness only scales time::

    T*(k, gamma) = T*_WB(k gamma) / sqrt(k)

``T*_WB`` is computed here by ``fsolve`` on the closed-form final state of the
antisymmetric 3-switch profile (switches ``T/2 - d, T/2, T/2 + d``; by
antisymmetry both velocities vanish, leaving position and deflection),
continued from the published ``gamma = 1`` optimum (4.2179 s).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import fsolve, minimize_scalar

from flexmotion_ros.cli.main import main
from flexmotion_ros.core import (
    ModalModel,
    PiecewiseConstant,
    PlannerConfig,
    final_state,
    load_config,
    simulate,
    two_mass,
)
from flexmotion_ros.core.config import read_parameter_file
from flexmotion_ros.core.design.optimize import optimize_design, write_design
from flexmotion_ros.core.design.problem import (
    DesignProblem,
    RobustnessRequirement,
    Task,
    problem_from_parameters,
)
from flexmotion_ros.core.design.space import DesignParameter
from flexmotion_ros.core.errors import FlexmotionError, SolverError

WB = ModalModel(b0=0.5, omega=[math.sqrt(2.0)], zeta=[0.0], b=[1.0])
CFG = PlannerConfig(model=WB)
CONFIG_DIR = Path(__file__).resolve().parents[3] / "config"
CONFIG_FILE = str(CONFIG_DIR / "design_two_mass.yaml")


class WieBernsteinTimes:
    """``T*_WB(gamma)`` by fsolve + continuation in ``gamma`` (independent of the planner)."""

    def __init__(self) -> None:
        self.table = [(1.0, 4.2179, 1.1053)]  # published optimum: T, half-spread of the switches

    @staticmethod
    def final(T: float, d: float) -> tuple[float, float]:
        """Closed-form ``p(T)``, ``q(T)`` of the WB system under the profile (from rest)."""
        t = np.array([0.0, T / 2 - d, T / 2, T / 2 + d, T])
        lev = np.array([1.0, -1.0, 1.0, -1.0])
        r = T - t  # time to go at each break
        p = 0.5 * float(lev @ (r[:-1] ** 2 - r[1:] ** 2) / 2.0)  # b0 int (T - t) u dt, b0 = 1/2
        w = math.sqrt(2.0)
        q = float(lev @ (np.cos(w * r[1:]) - np.cos(w * r[:-1]))) / w**2  # b int sin(w (T - t)) / w u dt
        return p, q

    def _solve(self, gamma: float, T0: float, d0: float) -> tuple[float, float]:
        def residual(z):
            p, q = self.final(*z)
            return [p - gamma, q]

        (T, d) = fsolve(residual, [T0, d0], xtol=1e-13)
        assert np.max(np.abs(residual([T, d]))) < 1e-11 and 0.0 < d < T / 2
        return float(T), float(d)

    def __call__(self, gamma: float) -> float:
        while self.table[-1][0] < gamma:  # continue the branch in small steps
            g, T, d = self.table[-1]
            g2 = min(gamma, g + 0.5)
            self.table.append((g2, *self._solve(g2, T * math.sqrt(g2 / g), d)))
        g, T, d = min(self.table, key=lambda r: abs(r[0] - gamma) if r[0] <= gamma else math.inf)
        return self._solve(gamma, T * math.sqrt(gamma / g), d)[0]


WB_TIMES = WieBernsteinTimes()


def independent_time(k: float, gamma: float) -> float:
    return WB_TIMES(k * gamma) / math.sqrt(k)


def problem(bounds, goals=(1.0,), weights=None, base=None, robustness=None) -> DesignProblem:
    weights = weights or [1.0] * len(goals)
    params = tuple(DesignParameter(n, lo, hi) for n, (lo, hi) in bounds.items())
    tasks = tuple(Task(g, w) for g, w in zip(goals, weights))
    return DesignProblem("two_mass", base or {"m1": 1.0, "m2": 1.0, "k": 7.0}, params, tasks, CFG, robustness)


@pytest.fixture(scope="module")
def two_task():
    """Tasks 1 m and 2 m (zero-vibration stiffnesses pi^2 and pi^2/2): an interior optimum in between."""
    pb = problem({"k": (5.5, 8.5)}, goals=(1.0, 2.0))
    return pb, optimize_design(pb, grid=5, xtol=1e-4)


def test_independent_reference_matches_published_optimum_and_simulation():
    T = WB_TIMES(1.0)
    assert T == pytest.approx(4.2179, abs=5e-5)
    T, d = WB_TIMES._solve(1.0, 4.2179, 1.1053)
    u = PiecewiseConstant.from_switches([T / 2 - d, T / 2, T / 2 + d], [1, -1, 1, -1], T)
    x = final_state(WB, WB.rest_state(), u)  # the closed form agrees with the exact simulation
    assert np.max(np.abs(x - WB.rest_state(1.0))) < 1e-12
    assert T > 2.0 * math.sqrt(2.0)  # above the rigid-body bound


def test_design_finds_the_optimum_of_the_independent_function(two_task):
    res = two_task[1]

    def J(k):
        return independent_time(k, 1.0) + independent_time(k, 2.0)

    ref = minimize_scalar(J, bounds=(5.5, 8.5), method="bounded", options={"xatol": 1e-7})
    assert 5.6 < ref.x < 8.4  # interior: the test is not about the bounds
    assert res.best["k"] == pytest.approx(ref.x, abs=2e-3)
    assert res.objective == pytest.approx(ref.fun, abs=1e-8)
    assert res.objective >= ref.fun - 1e-9  # never better than the true optimum
    for e in res.evaluations[:3]:  # every evaluated time is the independent one
        k = e.values[0]
        assert e.times == pytest.approx((independent_time(k, 1.0), independent_time(k, 2.0)), abs=1e-9)


def test_optimum_is_certified_and_reaches_the_target(two_task):
    pb, res = two_task
    assert res.certified
    model = two_mass(1.0, 1.0, res.best["k"]).model
    assert res.built.model == model
    for task, plan, T in zip(pb.tasks, res.evaluation.plans, res.evaluation.times):
        assert plan.continuous.certified, plan.continuous.certificate.message
        assert plan.continuous.duration == T
        x = simulate(model, model.rest_state(), plan.continuous.input(), times=[T])[0]
        assert np.max(np.abs(x - model.rest_state(task.gamma))) < 1e-9
        assert np.max(np.abs(plan.continuous.levels)) <= CFG.u_max


def test_bounds_respected_and_never_worse_than_grid_or_start(two_task):
    res = two_task[1]
    ks = [e.values[0] for e in res.evaluations if e is not res.start_evaluation]
    assert min(ks) >= 5.5 and max(ks) <= 8.5
    assert 5.5 <= res.best["k"] <= 8.5
    assert res.objective <= np.min(res.grid_objective)
    assert res.objective < res.start_evaluation.objective
    assert len({e.values for e in res.evaluations}) == len(res.evaluations)  # no point solved twice


def test_a_better_start_outside_the_bounds_is_not_reported():
    pb = problem({"k": (4.0, 5.0)}, base={"m1": 1.0, "m2": 1.0, "k": 9.0})  # k = 9 is faster than any k in [4, 5]
    res = optimize_design(pb, grid=3, xtol=0.3)
    assert res.start_evaluation.objective < res.objective
    assert 4.0 <= res.best["k"] <= 5.0


def test_optimum_at_bound_for_a_provable_reason():
    """Heavier m2 only raises the rigid-body bound 2 sqrt(gamma (m1 + m2) / u_max) <= T*.

    So no m2 whose bound exceeds T*(m2 = 1) can be better: the optimum lies in [1, m2c].
    """
    pb = problem({"m2": (1.0, 3.0)}, base={"m1": 1.0, "m2": 2.0, "k": 6.0})
    res = optimize_design(pb, grid=3, xtol=1e-2)
    t_lo = next(e.objective for e in res.evaluations if e.values == (1.0,))
    m2c = (t_lo / 2.0) ** 2 - 1.0
    assert 1.0 < m2c < 1.15  # a tight bracket, so the check can fail
    assert 1.0 <= res.best["m2"] <= m2c
    assert res.objective <= t_lo and res.certified


def test_two_parameters_stay_in_the_box_and_keep_the_rigid_argument():
    pb = problem({"k": (4.0, 6.0), "m2": (1.0, 2.0)}, base={"m1": 1.0, "m2": 1.5, "k": 5.0})
    res = optimize_design(pb, grid=3, xtol=0.02)
    assert res.certified
    for e in res.evaluations:
        assert 4.0 <= e.values[0] <= 6.0 and 1.0 <= e.values[1] <= 2.0
    assert res.objective <= np.min(res.grid_objective)
    m2c = (res.objective / 2.0) ** 2 - 1.0  # same argument as above, at the reported optimum
    assert res.best["m2"] <= m2c + 1e-12


def test_robustness_requirement_is_enforced():
    tight = RobustnessRequirement(frequency_error=0.05, max_residual=1e-12)
    with pytest.raises(SolverError, match="robust"):
        optimize_design(problem({"k": (5.0, 6.0)}, robustness=tight), grid=3, xtol=0.5)
    loose = RobustnessRequirement(frequency_error=0.05, max_residual=1.0)
    res = optimize_design(problem({"k": (5.0, 6.0)}, robustness=loose), grid=3, xtol=0.5)
    model = res.built.model
    u = res.evaluation.plans[0].continuous.input()
    worst = 0.0
    for e in np.linspace(-0.05, 0.05, 4):  # residual recomputed by hand: amplitude of q after the move
        m = model.with_changes(omega=(model.omega[0] * (1 + e),))
        q, qd = final_state(m, m.rest_state(), u)[2:4]
        worst = max(worst, math.hypot(q, qd / m.omega[0]))
    assert res.evaluation.residual == pytest.approx(worst, rel=1e-9)
    assert 0.0 < worst <= 1.0


@pytest.mark.parametrize(
    ("builder", "base", "name", "lo", "hi", "match"),
    [
        ("two_mass", None, "k", math.nan, 5.0, r"param k.*finite LO < HI, both > 0 N/m"),
        ("two_mass", None, "k", 1.0, math.inf, r"param k.*finite"),
        ("two_mass", None, "k", 5.0, 5.0, r"param k.*LO < HI"),
        ("two_mass", None, "k", 6.0, 5.0, r"param k"),
        ("two_mass", None, "k", -1.0, 5.0, r"param k: lower bound -1.0 is not physical.*> 0 N/m"),
        ("two_mass", None, "m1", 0.0, 5.0, r"param m1.*> 0 kg"),
        ("two_mass", None, "d", -0.1, 1.0, r"param d.*>= 0 N s/m"),
        ("two_mass", None, "kk", 1.0, 2.0, r"param kk: is not a design parameter of two_mass"),
        ("crane", {"cart_mass": 20, "payload_mass": 5, "cable_length": 2}, "zeta", 0.0, 1.0, r"param zeta.*\[0, 1\)"),
        (
            "chain",
            {"masses": [1, 1, 1], "springs": [1, 1]},
            "springs[2]",
            1.0,
            2.0,
            r"springs\[2\]: index must be in \[0, 1\]",
        ),
        ("chain", {"masses": [1, 1, 1], "springs": [1, 1]}, "springs", 1.0, 2.0, r"param springs: .*springs\[i\]"),
        ("chain", {"masses": [1, 1], "springs": [1]}, "dampers[0]", 0.0, 50.0, r"non-physical model.*overdamped"),
    ],
)
def test_bad_bounds_refused(builder, base, name, lo, hi, match):
    base = base or {"m1": 1.0, "m2": 1.0, "k": 1.0}
    with pytest.raises(FlexmotionError, match=match):
        DesignProblem(builder, base, (DesignParameter(name, lo, hi),), (Task(1.0),), CFG)


def test_other_bad_design_input_refused():
    with pytest.raises(FlexmotionError, match="param k: given more than once"):
        problem({"k": (1.0, 2.0)}).__class__(
            "two_mass",
            {"m1": 1, "m2": 1, "k": 1},
            (DesignParameter("k", 1, 2), DesignParameter("k", 2, 3)),
            (Task(1.0),),
            CFG,
        )
    with pytest.raises(FlexmotionError, match="a log scale needs lower bound > 0"):
        DesignProblem(
            "two_mass", {"m1": 1, "m2": 1, "k": 1}, (DesignParameter("d", 0.0, 1.0, "log"),), (Task(1.0),), CFG
        )
    with pytest.raises(FlexmotionError, match="goal: must be non-zero"):
        problem({"k": (1.0, 2.0)}, goals=(0.0,))
    with pytest.raises(FlexmotionError, match=r"weight\[0\]"):
        problem({"k": (1.0, 2.0)}, weights=[-1.0])
    with pytest.raises(FlexmotionError, match="design.k: is required"):
        DesignProblem("two_mass", {"m1": 1, "m2": 1}, (DesignParameter("m1", 1, 2),), (Task(1.0),), CFG)
    with pytest.raises(FlexmotionError, match="grid"):
        optimize_design(problem({"k": (1.0, 2.0)}), grid=2)


@settings(max_examples=60, deadline=None)
@given(
    lo=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e-300])),
    hi=st.floats(allow_nan=True, allow_infinity=True),
)
def test_bounds_accepted_only_if_physical(lo, hi):
    try:
        pb = problem({"k": (lo, hi)})
    except FlexmotionError as exc:
        assert exc.parameter == "param k"
        assert "> 0 N/m" in str(exc) or "non-physical" in str(exc)
        assert not (0.0 < lo < hi < math.inf) or "non-physical" in str(exc)
    else:
        assert 0.0 < lo < hi < math.inf
        p = pb.parameters[0]
        assert p.from_unit(0.0) == lo and p.from_unit(1.0) == hi


def test_written_file_loads_with_the_designed_model(two_task, tmp_path):
    res = two_task[1]
    out = tmp_path / "designed.yaml"
    write_design(out, res, "# test\n")
    cfg = load_config(out)
    assert cfg.model == two_mass(1.0, 1.0, res.best["k"]).model
    assert (cfg.u_max, cfg.rate_hz, cfg.method) == (CFG.u_max, CFG.rate_hz, CFG.method)
    # the design section records the structure: designing again starts at the optimum
    again, _ = problem_from_parameters(read_parameter_file(out), {"k": (5.5, 8.5)}, [1.0, 2.0])
    assert again.start() == pytest.approx(res.best, rel=1e-15)
    assert main(["plan", "--config", str(out), "--goal", "1.0"]) == 0


def test_cli_design_end_to_end(tmp_path, capsys):
    out, png = tmp_path / "o.yaml", tmp_path / "p.png"
    argv = ["design", "--config", CONFIG_FILE, "--param", "k=5.5:8.5", "--goal", "1", "--grid", "3", "--xtol", "0.2"]
    assert main([*argv, "--json", "--output", str(out), "--plot", str(png)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["certified"] and 5.5 <= data["best"]["k"] <= 8.5
    assert data["start"] == {"k": 1.0} and data["start_objective_s"] == pytest.approx(4.2179, abs=5e-5)
    assert load_config(out).model == two_mass(1.0, 1.0, data["best"]["k"]).model
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--param", "k=5:1", "--goal", "1"], "param k"),
        (["--param", "k=a:b", "--goal", "1"], "param k"),
        (["--param", "zz=1:2", "--goal", "1"], "param zz"),
        (["--param", "k=1:2"], "goal"),
        (["--param", "k=1:2", "--goal", "1", "--frequency-error", "0.1"], "max-residual"),
    ],
)
def test_cli_errors_one_line_exit_2(extra, match, capsys):
    assert main(["design", "--config", CONFIG_FILE, *extra]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.count("\n") == 1 and match in cap.err


def test_cli_modal_only_config_needs_a_builder(capsys):
    assert main(["design", "--config", str(CONFIG_DIR / "wie_bernstein.yaml"), "--param", "k=1:2", "--goal", "1"]) == 2
    assert "design.builder" in capsys.readouterr().err
    # with --builder/--set it designs (and notes nothing: the file's model is the same structure)
    argv = [
        "design",
        "--config",
        str(CONFIG_DIR / "wie_bernstein.yaml"),
        "--builder",
        "two_mass",
        "--set",
        "m1=1",
        "--set",
        "m2=1",
        "--set",
        "k=1",
        "--param",
        "k=1:1.5",
        "--goal",
        "1",
        "--grid",
        "3",
        "--xtol",
        "0.1",
    ]
    assert main(argv) == 0
    cap = capsys.readouterr()
    assert "best              k = 1.5" in cap.out and "note" not in cap.err
