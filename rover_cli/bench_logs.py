"""``rover bench logs``: recorder throughput and report time, against the mcap library measured alongside."""

from __future__ import annotations

import argparse
import json
from typing import Any

from rich.console import Console
from rich.table import Table as RichTable


def register(benchmarks: Any) -> None:
    bench = benchmarks.add_parser("logs", help="MCAP recorder throughput and report time of a long trial")
    bench.add_argument("--messages", type=int, default=200_000, help="messages per recorder contender")
    bench.add_argument(
        "--duration-s", type=float, default=600.0, help="simulated length of the reported trial"
    )
    bench.add_argument("--repeat", type=int, default=3, help="recorder runs per contender (best is kept)")
    bench.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    bench.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from logs.bench import run_benchmark

    console = Console()
    if args.messages <= 0 or args.duration_s <= 0 or args.repeat <= 0:
        console.print("[red]error:[/red] --messages, --duration-s and --repeat must be > 0")
        return 2
    figures = run_benchmark(args.messages, args.duration_s, args.repeat)
    if args.json:
        print(json.dumps(figures, sort_keys=True))
        return 0
    recorder = figures["recorder"]
    table = RichTable(
        title=f"recording {recorder['messages']} JSON messages ({recorder['json_mb']} MB), zstd"
    )
    for column in ("writer", "messages/s", "JSON MB/s", "file MB", "seconds"):
        table.add_column(column, justify="left" if column == "writer" else "right")
    for name in ("mcap_writer_json", "mcap_writer_raw", "recorder", "recorder_size_chunks"):
        row = recorder[name]
        table.add_row(
            name,
            f"{row['messages_per_s']:,}",
            str(row["json_mb_per_s"]),
            str(row["file_mb"]),
            str(row["seconds"]),
        )
    console.print(table)
    report = figures["report"]
    table = RichTable(
        title=f"report of a {report['duration_s']:.0f} s trial "
        f"({report['messages']:,} messages, {report['file_mb']} MB)"
    )
    table.add_column("step")
    table.add_column("seconds", justify="right")
    for name in ("mcap_reader_decode_all_s", "analyse_s", "report_tables_s", "report_with_plots_s"):
        table.add_row(name.removesuffix("_s"), str(report[name]))
    console.print(table)
    console.print("timings are wall time on this machine; rerun on a quiet machine for firm numbers")
    return 0
