"""Errors reach the console as written: brackets in a message are text, not rich markup."""

import io
from pathlib import Path

import pytest
from rich.console import Console

from rover_cli.errors import print_error
from rover_cli.main import main


def test_brackets_in_an_error_are_printed() -> None:
    out = io.StringIO()
    print_error(
        Console(file=out, width=200), ValueError("faults[0].offset_m: expected [x, y] with two numbers")
    )
    assert out.getvalue().strip() == "error: faults[0].offset_m: expected [x, y] with two numbers"


def test_emoji_codes_in_an_error_are_printed_as_written() -> None:
    # A CAN channel named x on the virtual interface: "virtual:x:" once came out as "virtual❌".
    out = io.StringIO()
    print_error(Console(file=out, width=200), ValueError("bus virtual:x: python-can's virtual bus refused"))
    assert out.getvalue().strip() == "error: bus virtual:x: python-can's virtual bus refused"


def test_the_logs_doctor_names_a_missing_file_with_brackets_in_its_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "trial[red].mcap"
    assert main(["logs", "doctor", str(missing)]) == 2
    assert "trial[red].mcap" in capsys.readouterr().out.replace("\n", "")
