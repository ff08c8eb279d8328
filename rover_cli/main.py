"""``rover`` entry point: one subcommand family per part of the stack.

Subcommand modules are imported only when picked, so ``rover run`` on the rover never imports the
simulator.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

# family -> module that defines ``register(subparsers)``
# (one line per family; keep the table sorted)
FAMILIES = {
    "bench": "rover_cli.bench_commands",
    "can": "rover_cli.can_commands",
    "hil": "rover_cli.hil_commands",
    "logs": "rover_cli.logs_commands",
    "plan": "rover_cli.plan_commands",
    "run": "rover_cli.run_commands",
    "telemetry": "rover_cli.telemetry_commands",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rover", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv for debug)")
    families = parser.add_subparsers(dest="family", required=True, metavar="COMMAND")
    for module_name in FAMILIES.values():
        module = importlib.import_module(module_name)
        module.register(families)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    handler = args.handler
    code: int = handler(args)
    return code


if __name__ == "__main__":
    sys.exit(main())
