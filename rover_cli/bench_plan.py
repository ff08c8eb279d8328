"""``rover bench plan``: our A* against pyastar2d and python-tcod on seeded maps (navigator.plan_bench)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from navigator.plan_bench_sizes import DEFAULT_SIZES
from rover_cli.arg_types import seed


def register(commands: Any) -> None:
    bench = commands.add_parser("plan", help="A*: ours vs pyastar2d and tcod; plan repair vs fresh plan")
    bench.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=list(DEFAULT_SIZES),
        help=f"map sizes, cells a side (default: {' '.join(map(str, DEFAULT_SIZES))})",
    )
    bench.add_argument("--repeats", type=int, default=3, help="runs per solver and size (median reported)")
    bench.add_argument("--seed", type=seed, default=1, help="seed of the generated inputs")
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run_bench)


def run_bench(args: argparse.Namespace) -> int:
    # Imported when picked: the benchmark's peers (scipy.sparse, pyastar2d, tcod) are no other command's cost.
    from navigator.plan_bench import SizeResult, obstacle_update_figures, repair_figures, run_size, warm_up

    warm_up()
    smallest = min(args.sizes)
    results: list[SizeResult] = [run_size(s, args.seed, args.repeats, s == smallest) for s in args.sizes]
    repair_size = 1024 if 1024 in args.sizes else max(args.sizes)
    repair = repair_figures(repair_size, args.seed, args.repeats)
    update = obstacle_update_figures(repair_size, args.seed, args.repeats)
    repairs_optimal = all(
        repair[f"{key}same_cost"] for key in ("", "window_", "off_path_", "off_path_window_")
    )
    all_optimal = all(all(r.checks.values()) for r in results) and repairs_optimal and update["same_grid"]
    if args.json:
        figures = {"sizes": [vars(r) for r in results], "repair": repair, "obstacle_update": update}
        print(json.dumps({**figures, "optimal": all_optimal}))
        return 0 if all_optimal else 1
    for r in results:
        print(f"{r.size} x {r.size}:")
        for name, ms in r.times_ms.items():
            expanded = r.expanded.get(name)
            cost = r.costs.get(name)
            print(
                f"  {name:<12} {ms:9.1f} ms   x{r.ratios[name]:5.2f} of pyastar2d"
                + (f"   expanded {expanded:>8}" if expanded is not None else "")
                + (f"   cost {cost:.6f}" if cost is not None else "")
            )
        print(f"  reference (scipy Dijkstra, planner's model): cost {r.costs['reference']:.6f}")
        print("  same cost: " + ", ".join(f"{name}: {ok}" for name, ok in r.checks.items()))
    print(
        f"repair on {repair['size']}^2 after a local change on the path: {repair['repair_ms']:.1f} ms vs "
        f"fresh plan {repair['fresh_ms']:.1f} ms ({100 * repair['ratio']:.1f} %), expanded "
        f"{repair['repair_expanded']} vs {repair['fresh_expanded']}, same cost: {repair['same_cost']}"
    )
    print(
        f"  told the change's window (as the planner does): {repair['window_repair_ms']:.1f} ms, "
        f"same cost: {repair['window_same_cost']}"
    )
    print(
        f"  change off the path: {repair['off_path_repair_ms']:.1f} ms "
        f"({100 * repair['off_path_ratio']:.1f} %), expanded {repair['off_path_repair_expanded']}, "
        f"same cost: {repair['off_path_same_cost']}; told its window: "
        f"{repair['off_path_window_repair_ms']:.1f} ms, same cost: {repair['off_path_window_same_cost']}"
    )
    print(
        f"  goal cost-to-go field (once per goal, reused by every repair): {repair['field_ms']:.1f} ms "
        f"({100 * repair['field_ratio']:.0f} % of a fresh plan)"
    )
    print(
        f"obstacle update on {update['size']}^2 (one rock): cost grid updated in its window "
        f"{update['update_ms']:.1f} ms vs made anew {update['full_ms']:.1f} ms "
        f"({100 * update['ratio']:.1f} %), same grid: {update['same_grid']}"
    )
    if not all_optimal:
        print("NOT OPTIMAL: a cost or grid differs from its reference (see 'same cost' / 'same grid' above)")
    return 0 if all_optimal else 1
