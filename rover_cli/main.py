"""``rover`` entry point: one subcommand family per part of the stack.

Subcommand modules are imported only when picked, so ``rover run`` on the rover never imports the
simulator, and no command pays for another's imports (the estimator benchmark's filterpy pulls in
scipy.stats: seconds of start-up). Only ``rover --help`` (or an unknown command) imports every family, to
list them.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence

from rover_cli.numba_cache import ensure_numba_cache

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


def build_parser(family: str | None = None) -> argparse.ArgumentParser:
    """The ``rover`` parser with every family, or with ``family``'s alone (the others not imported)."""
    parser = argparse.ArgumentParser(prog="rover", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv for debug)")
    families = parser.add_subparsers(dest="family", required=True, metavar="COMMAND")
    for name, module_name in FAMILIES.items():
        if family is None or name == family:
            importlib.import_module(module_name).register(families)
    return parser


def picked_family(argv: Sequence[str]) -> str | None:
    """The family the command line names (its first word that is not an option), if it is one of ours."""
    # The only top-level option (-v) takes no value, so the first non-option word is the family.
    first_word = next((word for word in argv if not word.startswith("-")), None)
    return first_word if first_word in FAMILIES else None


def main(argv: Sequence[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    # Before any family is imported: numba reads NUMBA_CACHE_DIR once, when it is first imported.
    numba_cache = ensure_numba_cache()
    parser = build_parser(picked_family(argv))
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    if numba_cache is not None:
        logging.getLogger(__name__).warning(
            "numba cache: %s; compiled kernels go to NUMBA_CACHE_DIR=%s (set NUMBA_CACHE_DIR to choose)",
            numba_cache.reason,
            numba_cache.path,
        )
    handler = args.handler
    try:
        code: int = handler(args)
        sys.stdout.flush()  # here, not at exit, so that a reader gone by then is caught below too
    except BrokenPipeError:
        return _reader_gone()
    return code


def _reader_gone() -> int:
    """Our stdout's reader went away (``rover plan MAP | head -3``): stop quietly with exit 1, as the
    commands that print through rich do. Stdout goes to /dev/null, so that the interpreter's last flush of
    what is still buffered does not fail again as a traceback."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # a stdout without a file descriptor (a test's stand-in)
        pass
    return 1


if __name__ == "__main__":
    sys.exit(main())
