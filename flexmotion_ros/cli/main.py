"""``flexmotion``: entry point and sub-command registry.

Each sub-command lives in its own module (imported here by name) with ``register(subparsers)``, which
adds its parser and sets ``func(args) -> int``.  Bad input raises
:class:`~flexmotion_ros.core.errors.FlexmotionError` (bad input or a planner that failed its checks);
it is printed as one line on stderr with exit status 2, and nothing goes to
stdout.
"""

from __future__ import annotations

import argparse
import os
import sys

from ..core.errors import FlexmotionError
from . import compare_cmd, demo_cmd, design_cmd, excite_cmd, identify_cmd, model_cmd, plan_cmd, shaper_cmd

#: Modules that provide sub-commands, in help order.
COMMAND_MODULES = (plan_cmd, model_cmd, design_cmd, shaper_cmd, compare_cmd, demo_cmd, excite_cmd, identify_cmd)


class _NegativeNumber:
    """Matches every negative number ``float()`` reads (``-5.03e-05``, ``-1E3``, ``-.5``, ``-inf``),
    and a comma-separated list of numbers that starts with one (``--goal -3.0,2.0``: one per rigid body).

    argparse's own pattern (``-1``, ``-1.5`` only) takes ``-5.03e-05`` for an
    option and fails with "expected one argument"; every parser of the
    command line uses this one instead (:class:`_Parser`).
    """

    def match(self, text: str) -> bool:
        if not text.startswith("-") or "_" in text:
            return False
        try:
            for part in text.split(","):
                float(part)
        except ValueError:
            return False
        return True


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit 2) and whose options take any negative number."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NegativeNumber()

    def error(self, message: str) -> None:  # one line, exit 2
        sys.stderr.write(f"flexmotion: error: {message}\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="flexmotion", description="Time-optimal, vibration-free moves for flexible machines.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for module in COMMAND_MODULES:
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``flexmotion``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except FlexmotionError as exc:
        message = " ".join(str(exc).split())  # always one line
        sys.stderr.write(f"flexmotion: error: {message}\n")
        return 2
    except BrokenPipeError:  # e.g. piped into head: not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


def entry() -> None:
    """Console-script entry point."""
    raise SystemExit(main())


if __name__ == "__main__":
    entry()
