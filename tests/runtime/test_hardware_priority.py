"""The simulated rover's process is raised to SCHED_FIFO where privilege allows, and says what it got."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from hil.hardware_priority import raise_to_fifo


@pytest.fixture
def sleeper() -> Iterator[subprocess.Popen[bytes]]:
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    yield process
    process.kill()
    process.wait()


def test_the_process_runs_at_fifo_or_the_refusal_is_said(sleeper: subprocess.Popen[bytes]) -> None:
    said = raise_to_fifo(sleeper.pid, 10)
    policy = os.sched_getscheduler(sleeper.pid)
    if said.startswith("SCHED_FIFO 10"):
        assert policy == os.SCHED_FIFO and os.sched_getparam(sleeper.pid).sched_priority == 10
    else:  # no privilege here: the peer keeps its policy and the table says why
        assert said.startswith("normal scheduling (SCHED_FIFO 10 refused:") and policy == os.SCHED_OTHER


def test_zero_leaves_the_process_as_it_is(sleeper: subprocess.Popen[bytes]) -> None:
    assert raise_to_fifo(sleeper.pid, 0) == "normal scheduling (--peer-fifo 0)"
    assert os.sched_getscheduler(sleeper.pid) == os.SCHED_OTHER


def test_a_process_that_is_gone_is_said_not_raised() -> None:
    said = raise_to_fifo(2**22 + 12345, 10)  # above the kernel's largest pid (2**22): no such process
    assert said.startswith("normal scheduling (SCHED_FIFO 10 refused:")


@pytest.mark.parametrize("priority", [-1, 100])
def test_a_priority_outside_1_to_99_is_refused(priority: int) -> None:
    with pytest.raises(ValueError, match="1-99"):
        raise_to_fifo(os.getpid(), priority)
