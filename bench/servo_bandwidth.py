"""What a real servo costs: a velocity- or position-commanded crane through a first-order servo.

The crane with the cart's acceleration as input (``crane_acceleration``, cable
``L``), the certified time-optimal ZOH move at ``--rate``, the setpoints of each
interface (velocity or position due at the end of each sample), then the plant
simulated exactly through the servo (``core.interfaces.simulate_servo``:
augmented matrix exponential, no integrator) with the hold after the move.
For each bandwidth, relative to the move:

* ``res@T``: residual swing amplitude at the planned arrival ``T`` (end of the last setpoint);
* ``pos@T``: cart position error at ``T``;
* ``settle``: time after ``T`` until position, velocity and swing stay within ``--tol`` of the move;
* ``res end``: residual swing after the servo has settled (end of the hold).

    python bench/servo_bandwidth.py
    python bench/servo_bandwidth.py --cable 5 --goal 3 --u-max 0.3 --rate 500
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from flexmotion_ros.core.config import PlannerConfig
from flexmotion_ros.core.interfaces import Servo, hold_setpoint, reference_for, setpoints, simulate_servo
from flexmotion_ros.core.methods.table import plan_move
from flexmotion_ros.core.model.boundary import rest_to_rest
from flexmotion_ros.core.model.builders import crane_acceleration
from flexmotion_ros.core.simulation.exact import modal_amplitudes

BANDWIDTHS = [None, 1000.0, 300.0, 100.0, 30.0, 10.0, 3.0, 1.0]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cable", type=float, default=2.0, help="cable length (m)")
    p.add_argument("--goal", type=float, default=2.0, help="move (m)")
    p.add_argument("--u-max", type=float, default=0.5, dest="u_max", help="cart acceleration bound (m/s^2)")
    p.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    p.add_argument("--tol", type=float, default=1e-6, help="settled: within this fraction of the move")
    a = p.parse_args()
    model = crane_acceleration(a.cable).model
    cfg = PlannerConfig(model=model, u_max=a.u_max, rate_hz=a.rate)
    t0 = time.perf_counter()
    plan = plan_move(cfg, rest_to_rest(model, a.u_max, a.goal), a.rate).sampled
    plan_ms = 1e3 * (time.perf_counter() - t0)
    dt = 1.0 / a.rate
    K = plan.samples
    print(
        f"# servo bandwidth (issue 14): crane, cart acceleration in, L = {a.cable} m "
        f"(swing {model.omega[0]:.4f} rad/s), move {a.goal} m, |a| <= {a.u_max} m/s^2, {a.rate:g} Hz: "
        f"T = {K * dt:.3f} s ({K} samples, planned in {plan_ms:.0f} ms); tolerance {a.tol:g} of the move"
    )
    print(f"{'interface':>9} {'bandwidth':>10} {'res@T':>9} {'pos@T':>9} {'settle s':>9} {'res end':>9}")
    print("-" * 60)
    for iface in ("velocity", "position"):
        ref = reference_for(model, plan.commands, dt, model.rest_state(0.0), iface)
        for w in BANDWIDTHS:
            hold_s = 2.0 if w is None else max(2.0, 40.0 / w)
            n_hold = int(math.ceil(hold_s * a.rate))
            values = np.concatenate([setpoints(ref, iface), np.full(n_hold, hold_setpoint(ref, iface))])
            run = simulate_servo(model, model.rest_state(0.0), values, dt, iface, Servo(bandwidth=w))
            after = run.states[K:]
            amp = modal_amplitudes(model, after)[:, 0] / a.goal
            err = np.maximum.reduce([np.abs(after[:, 0] - a.goal) / a.goal, np.abs(after[:, 1]) / a.goal, amp])
            out = np.flatnonzero(err > a.tol)
            settle = "0" if out.size == 0 else ("> hold" if out[-1] == err.size - 1 else f"{(out[-1] + 1) * dt:.3f}")
            label = "ideal" if w is None else f"{w:g} rad/s"
            print(
                f"{iface:>9} {label:>10} {amp[0]:9.1e} {abs(after[0, 0] - a.goal) / a.goal:9.1e} {settle:>9} {amp[-1]:9.1e}"
            )


if __name__ == "__main__":
    main()
