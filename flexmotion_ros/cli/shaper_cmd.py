"""``flexmotion shaper``: print an input shaper's impulses."""

from __future__ import annotations

import argparse
import json

from ..core.shaping.sensitivity import shaper_insensitivity
from ..core.shaping.shapers import SHAPERS, design


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("shaper", help="impulse times and amplitudes of an input shaper")
    p.add_argument("name", choices=sorted(SHAPERS), help="shaper")
    p.add_argument("--omega", type=_floats, required=True, help="natural frequency (rad/s); several: '2.0,5.1'")
    p.add_argument("--zeta", type=_floats, required=True, help="damping ratio(s), one per frequency")
    p.add_argument("--tolerance", type=float, default=0.05, help="EI vibration limit V (fraction, default 0.05)")
    p.add_argument(
        "--negative-amplitude",
        type=float,
        default=0.75,
        dest="negative_amplitude",
        help="SNA negative amplitude P (default 0.75)",
    )
    p.add_argument(
        "--multimode",
        choices=["convolve", "direct"],
        default="convolve",
        help="several modes: convolve per-mode shapers or design one directly (zv, zvd, zvdd)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object with 'times' and 'amplitudes'")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    shaper = design(args.name, args.omega, args.zeta, args.tolerance, args.negative_amplitude, args.multimode)
    widths = [shaper_insensitivity(shaper, 0.05, i).width for i in range(len(shaper.omega))]
    if args.json:
        out = shaper.to_dict()
        out["insensitivity_5pct"] = widths
        print(json.dumps(out))
        return 0
    lines = [
        f"shaper            {shaper.name} ({SHAPERS[args.name]})",
        (
            f"design            omega {', '.join(f'{w:g}' for w in shaper.omega)} rad/s, "
            f"zeta {', '.join(f'{z:g}' for z in shaper.zeta)}"
        ),
        f"solution          {'closed form' if shaper.exact else 'numerically solved constraints'}",
        f"duration          {shaper.duration:.9f} s",
        f"insensitivity 5 % {', '.join(f'{w:.4f}' for w in widths)} (frequency-ratio width per mode)",
        "impulses          time (s)          amplitude",
    ]
    lines += [
        f"  {i + 1:3d}             {t:.9f}   {a:+.9f}" for i, (t, a) in enumerate(zip(shaper.times, shaper.amplitudes))
    ]
    print("\n".join(lines))
    return 0
