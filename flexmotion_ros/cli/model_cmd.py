"""``flexmotion model``: write a parameter file from physical parameters."""

from __future__ import annotations

import argparse
import sys

from ..core.config import PlannerConfig
from ..core.errors import ModelError
from ..core.model.builders import INPUT_KINDS, BuiltModel, chain, crane, two_mass
from ..core.model.measurement import builder_map
from ..core.parameter_file import dump_parameters


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
    t.set_defaults(func=run, build=lambda a: two_mass(a.m1, a.m2, a.k, a.d))

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
    n.set_defaults(func=run, build=lambda a: chain(a.masses, a.springs, a.dampers, a.force_on))


def run(args: argparse.Namespace) -> int:
    built = args.build(args)
    config = PlannerConfig(model=built.model, u_max=args.u_max, rate_hz=args.rate)
    params = config.to_parameters()
    del params["limits.position_min"], params["limits.position_max"]
    # what the machine's sensors read (the plant's 'measurements' topic, identification)
    params.update(builder_map(built).to_parameters())
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
    text = dump_parameters(params, header)
    if args.output:
        with open(args.output, "w") as fh:
            fh.write(text)
        sys.stderr.write(f"wrote {args.output}\n")
    else:
        sys.stdout.write(text)
    return 0
