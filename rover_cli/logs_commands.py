"""``rover logs ...``: check, repair and report on MCAP recordings."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table as RichTable

from logs.errors import LogsError
from rover_cli import replay_commands
from rover_cli.errors import print_error


def register(families: Any) -> None:
    logs = families.add_parser("logs", help="check, repair and report on MCAP recordings")
    commands = logs.add_subparsers(dest="command", required=True, metavar="SUBCOMMAND")

    doctor = commands.add_parser(
        "doctor", help="structure, CRCs, summary and counts per topic of a recording"
    )
    doctor.add_argument("file", type=Path)
    doctor.add_argument("--json", action="store_true", help="print the findings as one JSON object")
    doctor.set_defaults(handler=doctor_command)

    recover = commands.add_parser(
        "recover", help="keep every complete chunk of a cut file; write a valid one"
    )
    recover.add_argument("file", type=Path)
    recover.add_argument("out", type=Path)
    recover.add_argument("--json", action="store_true", help="print the result as one JSON object")
    recover.set_defaults(handler=recover_command)

    report = commands.add_parser("report", help="HTML + Markdown + JSON report of one or more recordings")
    report.add_argument("inputs", type=Path, nargs="+", help="recordings and/or campaign directories")
    report.add_argument("--out", type=Path, required=True, help="folder for report.html/.md/.json")
    report.add_argument("--no-plots", action="store_true", help="tables only (faster)")
    report.add_argument(
        "--truth",
        type=Path,
        action="append",
        help="the ground truth (truth.mcap of `rover hil peer`) of a rover recording given: reported with it "
        "as one real-time HIL run, merged by log time; once per rover recording, paired in order",
    )
    report.set_defaults(handler=report_command)

    csv_columns = (
        "one CSV file per topic (truth/pose -> truth.pose.csv), a row a message: log_time_ns, log_time_s, "
        "then the message's fields flattened with dots (pose.position.x); a list of up to 16 items over "
        "indexed columns (wheels.0.erpm), a longer one as one JSON cell; for a spreadsheet or any CSV reader"
    )
    export = commands.add_parser("csv", help=csv_columns, description=csv_columns)
    export.add_argument("file", type=Path)
    export.add_argument("--out", type=Path, required=True, help="folder for the CSV files")
    export.add_argument(
        "--topics", type=lambda text: [t for t in text.split(",") if t], help="comma-separated (default: all)"
    )
    export.set_defaults(handler=csv_command)
    learned_help = (
        "what the rovers learned of their ground (navigator/learned), as [terrain_classes.<name>] tables "
        "for the rover config: the next run plans on it from the start"
    )
    learned = commands.add_parser("learned", help=learned_help, description=learned_help)
    learned.add_argument(
        "files",
        type=Path,
        nargs="+",
        help="recordings (trial.mcap, a rover's recording) and/or campaign folders",
    )
    learned.add_argument("--out", type=Path, help="write the tables to this file (default: print them)")
    learned.set_defaults(handler=learned_command)
    replay_commands.register(commands)


def doctor_command(args: argparse.Namespace) -> int:
    from logs.doctor import diagnose

    console = Console()
    try:
        report = diagnose(args.file)
    except LogsError as err:
        print_error(console, err)
        return 2
    if args.json:
        console.print_json(json.dumps(report.to_dict(), default=str))
        return 0 if report.healthy else 1
    state = "[green]healthy[/green]" if report.healthy else "[red]problems found[/red]"
    console.print(f"{report.path}: {state}; {report.size_bytes} bytes, library {report.library!r}")
    console.print(
        f"chunks {report.chunks} ({report.chunk_compression}), damaged {report.chunks_damaged}; "
        f"messages {report.messages}; data end {'yes' if report.complete else 'no'}, "
        f"summary {'yes' if report.summary_present else 'no'}, "
        f"footer {'yes' if report.footer_present else 'no'}, "
        f"data CRC {'n/a' if report.data_crc_ok is None else report.data_crc_ok}"
    )
    table = RichTable()
    for column in ("topic", "messages", "first (s)", "last (s)", "encoding"):
        table.add_column(
            column, justify="left" if column in ("topic", "encoding") else "right", overflow="fold"
        )
    for topic, summary in sorted(report.topics.items()):
        first = "" if summary.first_ns is None else f"{summary.first_ns / 1e9:.3f}"
        last = "" if summary.last_ns is None else f"{summary.last_ns / 1e9:.3f}"
        table.add_row(topic, str(summary.messages), first, last, summary.encoding)
    _print_table(console, table)
    console.print(
        f"metadata: {', '.join(report.metadata) or '-'}; attachments: {', '.join(report.attachments) or '-'}"
    )
    for problem in report.problems:
        console.print(f"[red]problem:[/red] {escape(problem)}")
    return 0 if report.healthy else 1


UNBOUNDED_WIDTH = 10_000  # columns: wider than any table these commands print


def _print_table(console: Console, table: RichTable) -> None:
    """``table`` whole. Piped to a file or a program, rich would fit it to 80 columns and cut topic names
    and paths with '…': there it gets the width it needs, one row a line. A terminal's narrower screen
    folds a long cell onto more lines (``overflow="fold"`` on the columns) rather than cutting it."""
    if not console.is_terminal:
        unbounded = console.options.update_width(UNBOUNDED_WIDTH)
        console.width = max(console.width, console.measure(table, options=unbounded).maximum)
    console.print(table)


def recover_command(args: argparse.Namespace) -> int:
    from logs.recover import recover

    console = Console()
    try:
        result = recover(args.file, args.out)
    except LogsError as err:
        print_error(console, err)
        return 2
    if args.json:
        console.print_json(json.dumps(result.to_dict()))
        return 0
    where = "complete file, copied" if result.was_complete else f"cut at byte {result.cut_at}"
    # Counts the reader can check with `rover logs doctor OUT`: the writer chunks the messages anew, so the
    # output's chunks are not the source's (kept 23, written 10).
    console.print(
        f"{result.source} ({where}) -> {result.output}: kept {result.messages} messages, "
        f"{result.metadata} metadata, {result.attachments} attachments (from {result.chunks_kept} complete "
        f"chunks read; written as {result.chunks_written} chunks); dropped {result.chunks_dropped} damaged "
        f"chunks, {result.orphan_messages} orphan messages"
    )
    return 0


def report_command(args: argparse.Namespace) -> int:
    from logs.report import unreadable_advice, write_report

    console = Console()
    try:
        result = write_report(args.inputs, args.out, plots=not args.no_plots, truth=args.truth)
    except LogsError as err:
        print_error(console, err)
        return 2
    for path, reason in result.failed.items():
        console.print(f"[yellow]skipped[/yellow] {escape(path)}: {escape(reason)}", soft_wrap=True)
    if result.failed:
        console.print(f"  {escape(unreadable_advice(result.damaged))}.", soft_wrap=True)
    unmerged = [run for run in result.runs if run.truth_path and not run.truth_merged]
    for run in result.runs:
        # The pairing's own problems name the truth file: said here, not only in the report.
        why = "; ".join(p for p in run.metrics.problems if str(run.truth_path) in p)
        if run.truth_path and run.truth_merged:
            console.print(
                f"real-time run: {escape(run.path)} + truth {escape(run.truth_path)}"
                + (f" [yellow]but[/yellow] {escape(why)}" if why else ""),
                soft_wrap=True,
            )
        elif run.truth_path:
            console.print(
                f"[yellow]truth not merged[/yellow] with {escape(run.path)}: {escape(why)}", soft_wrap=True
            )
        if run.missing:
            console.print(f"[yellow]partial[/yellow] {escape(run.path)}: missing {', '.join(run.missing)}")
    console.print(f"report: {result.html}\n        {result.markdown}\n        {result.json}")
    # 1: a report was written, but without some of the inputs (a script must not take it for all of them);
    # a --truth file that could not be merged is such an input.
    return 1 if result.failed or unmerged else 0


def csv_command(args: argparse.Namespace) -> int:
    """Exit 0: every message exported; 1: CSV files written from the part of a recording before a cut or
    damage (stderr says where); 2: bad input, nothing written."""
    from logs.csv_export import export_csv
    from logs.read_stop import partial_notice

    console = Console()
    try:
        result = export_csv(args.file, args.out, args.topics)
    except LogsError as err:
        print_error(console, err)
        return 2
    table = RichTable()
    for column in ("topic", "rows", "file"):
        table.add_column(column, justify="right" if column == "rows" else "left", overflow="fold")
    for topic, path in result.files.items():
        table.add_row(escape(topic), str(result.rows[topic]), escape(str(path)))
    _print_table(console, table)
    if result.skipped_messages:
        per_topic = ", ".join(
            f"{escape(topic)} {count} of {count + result.rows.get(topic, 0)}"
            + ("" if topic in result.files else " (no CSV)")
            for topic, count in result.undecodable.items()
        )
        console.print(
            f"[yellow]skipped[/yellow] {result.skipped_messages} message(s) that could not be decoded: "
            f"{per_topic} (the warnings say why)",
            soft_wrap=True,
        )
    if result.stop is not None:
        kept = f"the CSV files in {args.out} hold the {sum(result.rows.values())} messages before it"
        # As `rover can export` says it: one line on stderr, stdout stays the table.
        print(f"rover logs csv: {partial_notice(args.file, result.stop, kept)}", file=sys.stderr)
        return 1
    return 0


def learned_command(args: argparse.Namespace) -> int:
    """Exit 0: every recording read whole; 1: tables written from what could be read (a recording cut or
    damaged, or messages refused: stderr says which); 2: bad input, nothing written."""
    from logs.learned_terrain import learned_tables, read_learned
    from logs.read_stop import partial_notice
    from logs.report import expand_inputs
    from navigator.terrain_class_settings import override_refusal

    console = Console(stderr=True)
    files, _ = expand_inputs(args.files)  # a campaign's folder: every recording under it
    if not files:
        print_error(console, f"no recording (*.mcap) in {', '.join(str(f) for f in args.files)}")
        return 2
    try:
        read = read_learned(files, check=override_refusal)
    except LogsError as err:
        print_error(console, err)
        return 2
    tables = learned_tables(read)
    if args.out is None:
        sys.stdout.write(tables)
    else:
        try:
            args.out.write_text(tables, encoding="utf-8")
        except OSError as err:
            print_error(console, f"cannot write {args.out}: {err.strerror or err}")
            return 2
        console.print(f"{len(read.learnings)} learning(s) -> {escape(str(args.out))}")
    for source, stop in read.stops.items():
        kept = "the tables hold what was learned before it"
        print(f"rover logs learned: {partial_notice(source, stop, kept)}", file=sys.stderr)
    for why in read.refused:
        print(f"rover logs learned: refused a navigator/learned message: {why}", file=sys.stderr)
    return 1 if read.stops or read.refused else 0
