"""``flexmotion identify``: the modal model from a measured run (a CSV file), with 95 % intervals.

The parameter file it writes is one ``flexmotion plan --config`` and the nodes read: the
start file's other parameters (``--config``) with the identified model, or, without one,
``u_max`` = the largest ``|u|`` in the data and ``rate_hz`` = the data's sample rate.
"""

from __future__ import annotations

import argparse
import csv
import difflib
import json
import math
import sys
from pathlib import Path

import numpy as np

from ..core.config import PlannerConfig, load_config, write_config
from ..core.errors import InputError
from ..core.identification.data import SensorOutput
from ..core.identification.identify import DEFAULT_MAX_MODES, identify
from ..core.identification.response import OUTPUT_UNITS, OutputKind
from ..core.identification.result import IdentificationResult


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("identify", help="identify the modal model (b0, c, omega, zeta) from a measured run")
    p.add_argument("--data", required=True, help="CSV file with a header row (one column per signal)")
    p.add_argument("--time", required=True, help="column of the sample times (s), uniform")
    p.add_argument("--input", required=True, help="column of the command held from each sample to the next (N)")
    p.add_argument("--output", required=True, action="append", help="column of a measured output (repeatable)")
    p.add_argument(
        "--output-kind",
        dest="output_kind",
        action="append",
        choices=[k.value for k in OutputKind],
        help="what each output measures (one for all, or one per --output; default position)",
    )
    p.add_argument(
        "--rigid-weight",
        dest="rigid_weight",
        action="append",
        type=float,
        help="how much of the rigid-body coordinate each output reads (default 1: a body's coordinate; "
        "0: a relative one such as a rope angle)",
    )
    p.add_argument("--modes", type=int, help="number of vibration modes (default: selected by BIC)")
    p.add_argument(
        "--max-modes", type=int, default=DEFAULT_MAX_MODES, dest="max_modes", help="most modes tried when selecting"
    )
    p.add_argument("--config", help="start parameter file: its other parameters are kept, its model is the prior")
    p.add_argument("-o", "--output-file", dest="output_file", help="write the identified parameter file here")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="PNG: measured and fitted response, residuals, spectrum with the modes")
    p.set_defaults(func=run)


def read_columns(path: str, names: list[str]) -> dict[str, np.ndarray]:
    """Named numeric columns of a CSV file with a header row."""
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise InputError("--data", f"cannot read {path}: {exc.strerror or exc}") from None
    if not rows:
        raise InputError("--data", f"{path} is empty: expected a header row and one row per sample")
    header = [h.strip() for h in rows[0]]
    out = {}
    for name, option in names:
        if name not in header:
            close = difflib.get_close_matches(name, header, n=1, cutoff=0.5)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise InputError(option, f"no column {name!r} in {path}: {hint}(columns: {', '.join(header)})")
        j = header.index(name)
        values = []
        for i, row in enumerate(rows[1:], start=2):
            if not row:
                continue
            try:
                values.append(float(row[j]))
            except (ValueError, IndexError):
                cell = row[j] if j < len(row) else ""
                raise InputError(option, f"{path} line {i}, column {name!r}: {cell!r} is not a number") from None
        out[name] = np.array(values)
    return out


def _per_output(values: list | None, n: int, default, option: str) -> list:
    if not values:
        return [default] * n
    if len(values) == 1:
        return values * n
    if len(values) != n:
        raise InputError(option, f"give one value for all outputs or one per --output ({n}), got {len(values)}")
    return values


def run(args: argparse.Namespace) -> int:
    kinds = _per_output(args.output_kind, len(args.output), OutputKind.POSITION.value, "--output-kind")
    weights = _per_output(args.rigid_weight, len(args.output), 1.0, "--rigid-weight")
    config = load_config(args.config) if args.config else None
    names = [(args.time, "--time"), (args.input, "--input")] + [(o, "--output") for o in args.output]
    cols = read_columns(args.data, names)
    outputs = [
        SensorOutput(samples=cols[o], kind=OutputKind(k), rigid_weight=w, name=o)
        for o, k, w in zip(args.output, kinds, weights)
    ]
    if args.modes is not None and args.modes < 0:
        raise InputError("--modes", f"must be >= 0, got {args.modes}")
    result = identify(
        cols[args.time],
        cols[args.input],
        outputs,
        modes=args.modes,
        max_modes=args.max_modes,
        prior=config.model if config else None,
        u_max=config.u_max if config else None,
    )
    written = None
    if args.output_file:
        written = write_identified(args.output_file, result, config, cols[args.input], args.data)
    if args.plot:
        from ..plots.identification import plot_identification

        plot_identification(cols[args.time], cols[args.input], outputs, result, args.plot)
    if args.json:
        out = result.to_dict()
        if written:
            out["written"] = written
        print(json.dumps(out))
    else:
        print(text_summary(result))
    if written:
        sys.stderr.write(f"wrote {written}\n")
    return 0


def write_identified(path: str, result: IdentificationResult, config: PlannerConfig | None, u, source: str) -> str:
    """Write the identified model as a parameter file; returns the path."""
    prior_b = config.model.b if config is not None and config.model.n_modes == result.n_modes else None
    model = result.to_model(b=prior_b)
    if config is None:
        config = PlannerConfig(model=model, u_max=float(np.max(np.abs(u))), rate_hz=1.0 / result.dt)
        where = "u_max: the largest |u| in the data (set the actuator's bound); rate_hz: the data's rate"
    else:
        config = config.with_changes(model=model)
        where = "other parameters from the start file"
    lines = [f"# flexmotion identify --data {source}: {result.samples} samples at dt = {result.dt:.9g} s"]
    for i, m in enumerate(result.modes):
        lo, hi = m.omega.interval
        zlo, zhi = m.zeta.interval
        lines.append(
            f"# mode {i}: omega {m.omega.value:.6g} rad/s [{lo:.6g}, {hi:.6g}], zeta {m.zeta.value:.4g} "
            f"[{zlo:.4g}, {zhi:.4g}] (95 %)"
        )
    b_note = "from the start file" if prior_b is not None else "gain of output 0 (q_i read with weight 1)"
    lines.append(f"# b: {b_note}; rest-to-rest plans need only b0, c, omega, zeta")
    lines.append(f"# {where}")
    write_config(path, config, "\n".join(lines) + "\n")
    return str(Path(path))


def _est(e, fmt: str = ".6g") -> str:
    """``value +- std_error [lo, hi]`` with enough digits that the interval's ends differ."""
    lo, hi = e.interval
    if math.isfinite(e.std_error) and e.std_error > 0.0 and e.value != 0.0:
        digits = max(int(fmt[1:-1]), math.ceil(math.log10(abs(e.value) / e.std_error)) + 2)
        fmt = f".{min(digits, 15)}g"
    return f"{e.value:{fmt}} +- {e.std_error:.2g}  [{lo:{fmt}}, {hi:{fmt}}]"


def text_summary(result: IdentificationResult) -> str:
    """Human-readable summary of an identification."""
    outs = ", ".join(f"{o.name} ({o.kind})" for o in result.outputs)
    lines = [
        f"samples           {result.samples} (dt {result.dt:.6g} s, {result.samples * result.dt:.6g} s); outputs: {outs}",
        f"b0                {_est(result.b0)}  (95 %)",
        f"c                 {_est(result.c)} 1/s",
    ]
    for i, m in enumerate(result.modes):
        lines.append(f"mode {i}  omega    {_est(m.omega)} rad/s")
        lines.append(f"        zeta     {_est(m.zeta, '.4g')}")
        for j, g in enumerate(m.gains):
            lines.append(f"        gain[{j}]  {_est(g, '.4g')}  (a_{j}{i} b_{i})")
    for o in result.outputs:
        unit = OUTPUT_UNITS[o.kind]
        white = "white" if o.residual_correlation <= 2.0 * o.residual_correlation_bound else "NOT white"
        lines.append(
            f"fit {o.name:<13} noise std {o.noise_std:.3g} {unit}, residual rms {o.fit_rms:.3g} {unit}, "
            f"{o.fit_percent:.2f} %, residual correlation {o.residual_correlation:.3f} ({white}: "
            f"bound {o.residual_correlation_bound:.3f})"
        )
    sel = result.selection
    if sel.method == "given":
        lines.append(f"modes             {result.n_modes} (given)")
    else:
        crit = ", ".join(f"{k}: {v:.1f}" for k, v in sel.criterion.items())
        lines.append(f"modes             {result.n_modes} (smallest BIC; {crit})")
    if sel.first_estimate:
        lines.append(f"first estimate    {sel.first_estimate}, refined by maximum likelihood on the exact ZOH response")
    lines.append(
        f"solve time        {result.solve_time_s * 1e3:.1f} ms" + ("" if result.converged else " (NOT converged)")
    )
    lines.append(f"note              {result.planning_note}")
    return "\n".join(lines)
