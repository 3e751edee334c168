"""``flexmotion excite``: a bounded excitation for identification, written as a CSV command sequence.

The sequence (columns ``t`` in s and ``u`` in N, one row per command sample)
stays within ``u_max`` and the file's position limits and leaves the machine of
the file's model where it started, at rest (checked by exact propagation).
``flexmotion identify --data run.csv --time t --input u ...`` reads a recording
of it back.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from ..core.config import load_config
from ..core.errors import InputError
from ..core.identification.excitation import design_excitation, predicted_std_errors


def _band(text: str) -> tuple[float, float]:
    lo, sep, hi = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return float(lo), float(hi)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO:HI in rad/s (e.g. 0.5:5), got {text!r}") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("excite", help="design a bounded rest-to-rest excitation for identification (CSV)")
    p.add_argument("--config", required=True, help="parameter file: model, u_max, rate_hz, position limits")
    p.add_argument("--band", type=_band, required=True, help="frequency band LO:HI (rad/s, like model.omega)")
    p.add_argument("--duration", type=float, help="excitation length (s); default 4 periods of LO")
    p.add_argument("--tail", type=float, help="quiet tail after it (s); default a quarter of the duration")
    p.add_argument("--start", type=float, default=0.0, help="rigid-body position at the start (m)")
    p.add_argument(
        "--noise-std",
        type=float,
        default=1e-4,
        dest="noise_std",
        help="position-sensor noise (m) for the predicted standard errors (default 1e-4)",
    )
    p.add_argument("-o", "--output", help="CSV to write (columns t, u); default: stdout")
    p.add_argument("--json", action="store_true", help="print a JSON summary (with -o)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if not (math.isfinite(args.noise_std) and args.noise_std > 0.0):
        raise InputError("--noise-std", f"must be > 0 m, got {args.noise_std}")
    if args.json and not args.output:
        raise InputError("--json", "needs -o FILE for the sequence (stdout carries the JSON summary)")
    exc = design_excitation(
        config.model,
        config.u_max,
        config.rate_hz,
        args.band,
        duration=args.duration,
        tail=args.tail,
        position_limits=(config.position_min, config.position_max),
        start=args.start,
    )
    se_w, se_z = (
        predicted_std_errors(config.model, exc.commands, exc.dt, args.noise_std) if config.model.n_modes else ([], [])
    )
    rows = np.column_stack([exc.times, exc.commands])
    text = "t,u\n" + "\n".join(f"{t:.9g},{u:.17g}" for t, u in rows) + "\n"
    if args.output:
        with open(args.output, "w") as fh:
            fh.write(text)
    else:
        sys.stdout.write(text)
    summary = exc.to_dict()
    summary["predicted_omega_std_error"] = [float(x) for x in se_w]
    summary["predicted_zeta_std_error"] = [float(x) for x in se_z]
    summary["noise_std"] = args.noise_std
    if args.json:
        print(json.dumps(summary))
    else:
        lines = [
            f"wrote {args.output or 'stdout'}: {exc.commands.size} samples at {1.0 / exc.dt:g} Hz "
            f"({exc.excitation_duration:.6g} s excitation + {exc.duration - exc.excitation_duration:.6g} s quiet)",
            f"band {exc.band[0]:g}-{exc.band[1]:g} rad/s, {exc.lines.size} lines; peak |u| {exc.peak:.6g} "
            f"(set by {exc.bound}); position range [{exc.position_range[0]:.6g}, {exc.position_range[1]:.6g}] m",
            f"ends where it started, at rest: relative final-state error {exc.final_state_error:.1e} (exact propagation)",
        ]
        for i, (w, sw, sz) in enumerate(zip(config.model.omega, se_w, se_z)):
            inside = "" if exc.band[0] <= w <= exc.band[1] else "  (outside the band: weakly excited)"
            lines.append(
                f"mode {i} ({w:.6g} rad/s): predicted std error omega {sw:.2g} rad/s, zeta {sz:.2g} "
                f"at {args.noise_std:g} m position noise{inside}"
            )
        # the summary goes to stdout when the sequence went to a file, else to stderr beside the CSV
        (sys.stdout if args.output else sys.stderr).write("\n".join(lines) + "\n")
    return 0
