"""``rover bench estimator``: our EKF vs a plain filterpy EKF of the same model (estimator.bench)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from rover_cli.arg_types import seed


def register(commands: Any) -> None:
    bench = commands.add_parser(
        "estimator", help="EKF: us per predict / update and full cycles per second, ours vs filterpy"
    )
    bench.add_argument("--cycles", type=int, default=20_000, help="50 Hz sensor cycles per timing run")
    bench.add_argument("--repeats", type=int, default=3, help="timing runs per contender (fastest reported)")
    bench.add_argument("--seed", type=seed, default=1, help="seed of the generated inputs")
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    # Imported here: filterpy (the peer) imports scipy.stats, seconds that no other command should pay.
    from estimator.bench import run_benchmark

    if args.cycles < 100 or args.repeats < 1:
        raise SystemExit("rover bench estimator: need --cycles >= 100 and --repeats >= 1")
    figures = run_benchmark(args.cycles, args.seed, args.repeats)
    if args.json:
        print(json.dumps(figures))
        return 0
    rates = figures["cycles_per_s"]
    print(f"full cycles per second ({figures['cycle']}; {args.cycles} cycles, best of {args.repeats}):")
    for name, rate in rates.items():
        print(f"  {name:<15} {rate:10.0f} /s   x{rate / rates['filterpy']:5.2f} of filterpy")
    verdict = "met" if figures["goal_met"] else "NOT met"
    print(f"  goal {figures['goal_cycles_per_s']:.0f} /s on one core: {verdict}")
    print("microseconds per operation (inside realistic cycles):")
    ours, peer = figures["us_per_operation"]["ours"], figures["us_per_operation"]["filterpy"]
    for name in ours:
        ratio = peer[name] / ours[name]
        print(f"  {name:<16} ours {ours[name]:7.2f} us   filterpy {peer[name]:7.2f} us   x{ratio:5.2f}")
    return 0
