"""``flexmotion model``: write a parameter file from physical parameters."""

from __future__ import annotations

import argparse
import sys

from ..core.config import PlannerConfig
from ..core.model.builders import chain, crane, two_mass
from ..core.parameter_file import dump_parameters


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.replace(",", " ").split()]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("model", help="write a parameter file from physical parameters")
    kinds = p.add_subparsers(dest="kind", required=True, parser_class=type(p))
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--u-max", type=float, default=1.0, dest="u_max", help="actuator bound (N)")
    common.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    common.add_argument("-o", "--output", help="file to write (default: stdout)")

    t = kinds.add_parser("two-mass", parents=[common], help="two masses, spring, damper; force on mass 1")
    t.add_argument("--m1", type=float, required=True, help="mass 1 (kg), pushed")
    t.add_argument("--m2", type=float, required=True, help="mass 2 (kg)")
    t.add_argument("--k", type=float, required=True, help="spring (N/m)")
    t.add_argument("--d", type=float, default=0.0, help="damper (N s/m)")
    t.set_defaults(func=run, build=lambda a: two_mass(a.m1, a.m2, a.k, a.d))

    c = kinds.add_parser("crane", parents=[common], help="overhead crane (cart + payload on a cable)")
    c.add_argument("--cart-mass", type=float, required=True, dest="cart_mass", help="cart mass (kg)")
    c.add_argument("--payload-mass", type=float, required=True, dest="payload_mass", help="payload mass (kg)")
    c.add_argument("--cable-length", type=float, required=True, dest="cable_length", help="cable length (m)")
    c.add_argument("--g", type=float, default=9.81, help="gravity (m/s^2)")
    c.add_argument("--zeta", type=float, default=0.0, help="swing damping ratio")
    c.set_defaults(func=run, build=lambda a: crane(a.cart_mass, a.payload_mass, a.cable_length, a.g, a.zeta))

    n = kinds.add_parser("chain", parents=[common], help="n masses joined by springs; force on one")
    n.add_argument("--masses", type=_floats, required=True, help="masses (kg), e.g. '1,1,1'")
    n.add_argument("--springs", type=_floats, required=True, help="springs between neighbours (N/m)")
    n.add_argument("--dampers", type=_floats, default=None, help="dampers in parallel (N s/m)")
    n.add_argument("--force-on", type=int, default=0, dest="force_on", help="index of the pushed mass")
    n.set_defaults(func=run, build=lambda a: chain(a.masses, a.springs, a.dampers, a.force_on))


def run(args: argparse.Namespace) -> int:
    built = args.build(args)
    config = PlannerConfig(model=built.model, u_max=args.u_max, rate_hz=args.rate)
    params = config.to_parameters()
    del params["limits.position_min"], params["limits.position_max"]
    desc = ", ".join(f"{k}={v}" for k, v in built.parameters.items())
    meaning = (
        "mode: payload offset from the cart (m)"
        if built.kind == "crane"
        else "modal coordinates: largest spring deflection of each mode (m)"
    )
    header = f"# flexmotion model {args.kind}: {desc}\n# {meaning}\n"
    text = dump_parameters(params, header)
    if args.output:
        with open(args.output, "w") as fh:
            fh.write(text)
        sys.stderr.write(f"wrote {args.output}\n")
    else:
        sys.stdout.write(text)
    return 0
