"""``flexmotion model``: write a parameter file from physical parameters.

One drive: ``two-mass``, ``crane``, ``chain``.  Several drives (:mod:`.multi_model`):
``gantry``, ``chain --actuated 0,3`` and ``two-mass --actuated 0,1``.
"""

from __future__ import annotations

import argparse
import sys

from ..core.config import PlannerConfig
from ..core.errors import ModelError
from ..core.model.builders import INPUT_KINDS, BuiltModel, chain, crane, two_mass
from ..core.parameter_file import dump_parameters
from . import multi_model


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.replace(",", " ").split()]


def _crane(a: argparse.Namespace) -> BuiltModel:
    if a.input == "force":
        for name in ("cart_mass", "payload_mass"):
            if getattr(a, name) is None:
                flag = "--" + name.replace("_", "-")
                raise ModelError(name, f"{flag} is required with --input force (kg, > 0)")
    return crane(a.cart_mass, a.payload_mass, a.cable_length, a.g, a.zeta, input=a.input)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("model", help="write a parameter file from physical parameters")
    kinds = p.add_subparsers(dest="kind", required=True, parser_class=type(p))
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--u-max", type=float, default=1.0, dest="u_max", help="actuator bound (N; m/s^2 with --input acceleration)"
    )
    common.add_argument("--rate", type=float, default=1000.0, help="command rate (Hz)")
    common.add_argument("-o", "--output", help="file to write (default: stdout)")

    t = kinds.add_parser("two-mass", parents=[common], help="two masses, spring, damper; force on mass 1")
    t.add_argument("--m1", type=float, required=True, help="mass 1 (kg), pushed")
    t.add_argument("--m2", type=float, required=True, help="mass 2 (kg)")
    t.add_argument("--k", type=float, required=True, help="spring (N/m)")
    t.add_argument("--d", type=float, default=0.0, help="damper (N s/m)")
    _actuated_options(t)
    t.set_defaults(func=run, build=lambda a: two_mass(a.m1, a.m2, a.k, a.d), multi=multi_model.build_two_mass)

    c = kinds.add_parser("crane", parents=[common], help="overhead crane (cart + payload on a cable)")
    c.add_argument("--cart-mass", type=float, dest="cart_mass", help="cart mass (kg); --input force only")
    c.add_argument("--payload-mass", type=float, dest="payload_mass", help="payload mass (kg); --input force only")
    c.add_argument("--cable-length", type=float, required=True, dest="cable_length", help="cable length (m)")
    c.add_argument("--g", type=float, default=9.81, help="gravity (m/s^2)")
    c.add_argument("--zeta", type=float, default=0.0, help="swing damping ratio")
    c.add_argument(
        "--input",
        choices=INPUT_KINDS,
        default="force",
        help="force: N on the cart (effort joint); acceleration: the cart's acceleration (m/s^2) imposed by a "
        "velocity- or position-controlled drive, --u-max is then the acceleration bound",
    )
    c.set_defaults(func=run, build=_crane)

    n = kinds.add_parser("chain", parents=[common], help="n masses joined by springs; force on one")
    n.add_argument("--masses", type=_floats, required=True, help="masses (kg), e.g. '1,1,1'")
    n.add_argument("--springs", type=_floats, required=True, help="springs between neighbours (N/m)")
    n.add_argument("--dampers", type=_floats, default=None, help="dampers in parallel (N s/m)")
    n.add_argument("--force-on", type=int, default=0, dest="force_on", help="index of the pushed mass")
    _actuated_options(n)
    n.set_defaults(
        func=run, build=lambda a: chain(a.masses, a.springs, a.dampers, a.force_on), multi=multi_model.build_chain
    )

    g = kinds.add_parser(
        "gantry",
        parents=[common],
        help="gantry crane, two drives: trolley (x) on a bridge (y), payload on a rope (one swing mode per axis)",
    )
    g.add_argument("--trolley-mass", type=float, required=True, dest="trolley_mass", help="trolley mass (kg)")
    g.add_argument("--bridge-mass", type=float, required=True, dest="bridge_mass", help="bridge mass (kg)")
    g.add_argument("--payload-mass", type=float, required=True, dest="payload_mass", help="payload mass (kg)")
    g.add_argument("--rope-length", type=float, required=True, dest="rope_length", help="rope length (m)")
    g.add_argument("--g", type=float, default=9.81, help="gravity (m/s^2)")
    g.add_argument("--zeta", type=float, default=0.0, help="swing damping ratio")
    g.add_argument("--trolley-force", type=float, default=1.0, dest="trolley_force", help="trolley drive bound (N)")
    g.add_argument("--bridge-force", type=float, default=1.0, dest="bridge_force", help="bridge drive bound (N)")
    g.set_defaults(func=run_multi, build=multi_model.build_gantry)


def _actuated_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--actuated",
        help="several drives: the pushed masses' indices, e.g. 0,3 (a multi-input file; one input per mass)",
    )
    p.add_argument(
        "--u-max-each",
        dest="u_max_list",
        help="with --actuated: one force bound per drive (N), e.g. 10,20 (default: --u-max for every drive)",
    )


def _write(args: argparse.Namespace, text: str) -> int:
    if args.output:
        with open(args.output, "w") as fh:
            fh.write(text)
        sys.stderr.write(f"wrote {args.output}\n")
    else:
        sys.stdout.write(text)
    return 0


def run_multi(args: argparse.Namespace) -> int:
    """A multi-input parameter file with the map to physical coordinates in its header."""
    built = args.build(args)
    return _write(args, multi_model.text(built, args.kind, args.rate))


def run(args: argparse.Namespace) -> int:
    if getattr(args, "actuated", None) is not None:
        args.build = args.multi
        return run_multi(args)
    if getattr(args, "u_max_list", None) is not None:
        raise ModelError("u_max_each", "is for several drives: give --actuated too (else --u-max)")
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
    if built.parameters.get("input") == "acceleration":
        header += (
            f"# input: {built.notes['input']}; u_max is the acceleration bound (m/s^2); "
            "rigid body: the cart (b0 = 1); for a velocity- or position-commanded drive\n"
        )
    return _write(args, dump_parameters(params, header))
