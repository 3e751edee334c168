"""Identification accuracy and speed (issue 13): ours against the Cramer-Rao bound and a Klipper-style estimate.

Three machines, 10^4 samples each, white noise at 30 dB, the excitation
``flexmotion excite`` designs for each (band 0.3 x the first to 3 x the last
mode, 80 % excitation then a quiet tail), the true machine's output simulated
exactly (matrix exponential of the whole model, state by state):

* two-mass (m1 = m2 = 1 kg, k = 1 N/m, d = 0.05 N s/m), encoder on the far mass, dt = 10 ms;
* crane (20 kg cart, 5 kg payload, 2 m cable, swing zeta 0.01, drag c = -0.05 1/s), cart encoder, dt = 5 ms;
* lumped beam (4 x 0.5 kg, 400 N/m, 0.4 N s/m: 21.6, 40.0, 52.3 rad/s), tip accelerometer, dt = 1 ms.

Per mode, over the same noise seeds: bias and standard deviation of omega and
zeta from ``identify`` (modes given), the Cramer-Rao bound at the truth
(``predicted_std_errors``, the Fisher information of the exact response), and
the Klipper-style estimate on the same data: Welch cross-spectral transfer
estimate ``|P_yu| / P_uu`` (Hann, 3 half-overlapping segments of N / 2: the finest resolution Welch averaging allows; a position's
turned into the acceleration's, as Klipper measures acceleration), the highest
peak within +-30 % of the true frequency (a generous search window, cut at the
midpoint to a neighbouring mode) for omega,
the half-power width (linear interpolation of ``|H|^2`` around the peak) for
zeta = width / (2 omega) ("fail": no half-power point inside the window, no
damping estimate; the rms ratio is over the others).  Timing: median and 95th
percentile wall and CPU time of one ``identify`` call on 10^4 samples.

Run: ``OPENBLAS_NUM_THREADS=1 python bench/identification.py [--seeds 50]``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np
from scipy.linalg import expm
from scipy.signal import csd, welch

from flexmotion_ros.core.identification import SensorOutput, identify
from flexmotion_ros.core.identification.excitation import design_excitation, predicted_std_errors
from flexmotion_ros.core.model.builders import chain, crane, two_mass

N = 10_000
SNR_DB = 30.0


def simulate(model, a0, a, u, dt, kind):
    """Exact sensor output at each sample (after the command is applied), whole-model expm."""
    A, B = model.A(), model.B()
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B
    E = expm(M * dt)
    Phi, Gam = E[:n, :n], E[:n, n]
    X = np.empty((u.size, n))
    x = np.zeros(n)
    for k, uk in enumerate(u):
        X[k] = x
        x = Phi @ x + Gam * uk
    cp = np.zeros(n)
    cp[0], cp[2::2] = a0, a
    cv = np.zeros(n)
    cv[1], cv[3::2] = a0, a
    if kind == "position":
        return X @ cp
    return (X @ A.T + np.outer(u, B)) @ cv


def machines():
    tm = two_mass(1.0, 1.0, 1.0, 0.05)
    cr = crane(20.0, 5.0, 2.0, zeta=0.01)
    bm = chain([0.5] * 4, [400.0] * 3, [0.4] * 3)
    return [
        ("two-mass, far encoder", tm.model, 1.0, tm.modal_to_physical[1, 1:], 0.01, "position", 1.0),
        (
            "crane + drag, cart encoder",
            cr.model.with_changes(c=-0.05),
            1.0,
            cr.modal_to_physical[0, 1:],
            0.005,
            "position",
            50.0,
        ),
        ("beam, tip accelerometer", bm.model, 1.0, bm.modal_to_physical[3, 1:], 0.001, "acceleration", 10.0),
    ]


def klipper_style(u, y, dt, omega_true, kind):
    """Welch transfer estimate: peak frequency and half-power damping near each true frequency.

    A position's transfer is turned into the acceleration's (times omega^4 in power), as Klipper
    measures with an accelerometer: the rigid body's 1/omega^2 slope would bury the peak.
    """
    fs = 1.0 / dt
    nper = y.size // 2
    f, puu = welch(u, fs=fs, nperseg=nper)
    _, pyu = csd(y, u, fs=fs, nperseg=nper)
    w = 2.0 * math.pi * f
    h2 = np.abs(pyu / np.maximum(puu, 1e-300)) ** 2
    if kind == "position":
        h2 = h2 * w**4
    out = []
    for i, wt in enumerate(omega_true):
        # +-30 %, but never past the midpoint to a neighbouring mode
        lo_edge = max(0.7 * wt, 0.5 * (wt + omega_true[i - 1]) if i > 0 else 0.0)
        hi_edge = min(1.3 * wt, 0.5 * (wt + omega_true[i + 1]) if i + 1 < len(omega_true) else math.inf)
        win = np.flatnonzero((w >= lo_edge) & (w <= hi_edge))
        k = int(win[np.argmax(h2[win])])
        half = h2[k] / 2.0
        lo = k
        while lo > win[0] and h2[lo] > half:
            lo -= 1
        hi = k
        while hi < win[-1] and h2[hi] > half:
            hi += 1
        if h2[lo] > half or h2[hi] > half:  # no half-power point inside the window: no damping estimate
            out.append((w[k], math.nan))
            continue
        w_lo = w[lo] + (half - h2[lo]) * (w[lo + 1] - w[lo]) / (h2[lo + 1] - h2[lo])
        w_hi = w[hi - 1] + (half - h2[hi - 1]) * (w[hi] - w[hi - 1]) / (h2[hi] - h2[hi - 1])
        out.append((w[k], (w_hi - w_lo) / (2.0 * w[k])))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    args = parser.parse_args()
    import numpy  # noqa: F401  (version in the header)

    print(
        f"# identification (issue 13): python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), load {os.getloadavg()[0]:.1f}; {N} samples, SNR {SNR_DB:g} dB, {args.seeds} seeds"
    )
    header = (
        f"{'machine':<28}{'mode':>5}{'omega':>9}{'zeta':>8} | {'ours: w bias':>12}{'w std':>9}{'w CRB':>9}"
        f"{'z bias':>10}{'z std':>9}{'z CRB':>9} | {'Klipper: w bias':>15}{'w std':>9}{'z bias':>10}{'z std':>9}{'fail':>6}"
        f" | {'z rms K/ours':>12}"
    )
    print(header)
    print("-" * len(header))
    timings = []
    for name, model, a0, a, dt, kind, u_max in machines():
        band = (0.3 * min(model.omega), min(3.0 * max(model.omega), 0.7 * math.pi / dt))
        exc = design_excitation(model, u_max, 1.0 / dt, band, duration=0.8 * N * dt, tail=0.2 * N * dt)
        u = exc.commands[:N]
        t = dt * np.arange(u.size)
        clean = simulate(model, a0, a, u, dt, kind)
        sigma = float(np.std(clean)) / 10 ** (SNR_DB / 20.0)
        crb_w, crb_z = predicted_std_errors(model, u, dt, sigma, kind=kind, weights=tuple(a))
        ours_w, ours_z, kl_w, kl_z, times = [], [], [], [], []
        for seed in range(args.seeds):
            y = clean + sigma * np.random.default_rng(seed).standard_normal(u.size)
            t0, c0 = time.perf_counter(), time.process_time()
            r = identify(t, u, SensorOutput(samples=y, kind=kind), modes=model.n_modes)
            times.append((time.perf_counter() - t0, time.process_time() - c0))
            ours_w.append([m.omega.value for m in r.modes])
            ours_z.append([m.zeta.value for m in r.modes])
            k = klipper_style(u, y, dt, model.omega, kind)
            kl_w.append([x[0] for x in k])
            kl_z.append([x[1] for x in k])
        ours_w, ours_z, kl_w, kl_z = (np.array(v) for v in (ours_w, ours_z, kl_w, kl_z))
        w0, z0 = np.array(model.omega), np.array(model.zeta)
        for i in range(model.n_modes):
            ew, ez = ours_w[:, i] - w0[i], ours_z[:, i] - z0[i]
            kw, kz = kl_w[:, i] - w0[i], kl_z[:, i] - z0[i]
            failed = int(np.isnan(kz).sum())
            ok = kz[~np.isnan(kz)]
            kz_bias, kz_std = (ok.mean(), ok.std()) if ok.size else (math.nan, math.nan)
            ratio = math.sqrt(np.mean(ok**2)) / math.sqrt(np.mean(ez**2)) if ok.size else math.nan
            print(
                f"{name if i == 0 else '':<28}{i:>5}{w0[i]:>9.4g}{z0[i]:>8.4f} | {ew.mean():>12.1e}{ew.std():>9.1e}"
                f"{crb_w[i]:>9.1e}{ez.mean():>10.1e}{ez.std():>9.1e}{crb_z[i]:>9.1e} | {kw.mean():>15.1e}"
                f"{kw.std():>9.1e}{kz_bias:>10.1e}{kz_std:>9.1e}{failed:>6} | {ratio:>12.0f}"
            )
        wall, cpu = np.array(times).T
        timings.append((name, np.median(wall), np.percentile(wall, 95), np.median(cpu), np.percentile(cpu, 95)))
    print()
    print(
        f"{'machine':<28}{'identify wall median ms':>24}{'p95 ms':>10}{'CPU median ms':>15}{'p95 ms':>10}"
        f"   ({N} samples, modes given; CPU = this process's time, what a loaded machine does not inflate)"
    )
    for name, med, p95, cmed, cp95 in timings:
        print(f"{name:<28}{med * 1e3:>24.1f}{p95 * 1e3:>10.1f}{cmed * 1e3:>15.1f}{cp95 * 1e3:>10.1f}")


if __name__ == "__main__":
    main()
