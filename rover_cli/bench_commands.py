"""``rover bench ...``: benchmarks that print figures against named peers measured in the same run.

Each benchmark lives in its own module with ``register(subparsers)``; this table names them. Every
benchmark takes ``--json`` and then prints the same figures as one JSON object.
"""

from __future__ import annotations

import importlib
from typing import Any

# benchmark name -> module (one line per benchmark; keep the table sorted)
BENCHMARKS: dict[str, str] = {
    "can": "rover_cli.bench_can",
    "estimator": "rover_cli.bench_estimator",
    "hil": "rover_cli.bench_hil",
    "logs": "rover_cli.bench_logs",
    "plan": "rover_cli.bench_plan",
    "runtime": "rover_cli.bench_runtime",
}


def register(families: Any) -> None:
    bench = families.add_parser("bench", help="benchmarks against named peers, measured in the same run")
    commands = bench.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    for module_name in BENCHMARKS.values():
        importlib.import_module(module_name).register(commands)
