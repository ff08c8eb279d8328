"""What a path given to ``rover logs report`` is, when it is not a recording: checked before anything is read
or written, so a typo or a scenario given in a recording's place is refused rather than reported as an
empty run ("skipped ... not an MCAP file", an empty report, advice to recover the file).

Only what can be told from the file's name and first bytes: a file that is MCAP (or starts as MCAP and is
cut inside its magic: a recorder that died) is left to the reader, which says what is wrong inside it.
"""

from __future__ import annotations

from pathlib import Path

from logs.file_kinds import CAMPAIGN, ROVER_CONFIG, SCENARIO, evidence, kind_of
from logs.frames import MCAP_MAGIC
from logs.settings import ConfigError, Table, parse_toml

# Enough to tell a scenario, a campaign or a config by its top-level keys; a larger text is not one of ours.
_TOML_READ_LIMIT = 1 << 20
# What to do with a file of each kind instead of reporting on it.
_INSTEAD = {
    SCENARIO: "; `rover hil trial` records a run of it",
    CAMPAIGN: "; give the folder it recorded its trials into",
    ROVER_CONFIG: "",
}


def not_a_recording(path: Path) -> str | None:
    """Why ``path`` (given as a file) is no recording: missing, not a file, or another kind of file (a
    TOML scenario, campaign or config, or bytes that are not MCAP); None when it may be one."""
    if not path.exists():
        return f"{path} does not exist"
    if not path.is_file():
        return f"{path} is not a file"
    try:
        with path.open("rb") as stream:
            head = stream.read(len(MCAP_MAGIC))
    except OSError:
        return None  # unreadable: the reader names the operating system's reason
    if MCAP_MAGIC.startswith(head):
        return None
    return f"{path} is {_what_it_is(path)}, not an MCAP recording"


def _what_it_is(path: Path) -> str:
    root = _toml_table(path)
    if root is None:
        with path.open("rb") as stream:
            return f"not an MCAP file (it starts with {stream.read(len(MCAP_MAGIC))!r})"
    kind = kind_of(root)  # the settings loaders' own test (logs.file_kinds): one mechanism
    if kind is None:
        return "a TOML file"
    return f"a TOML {kind.noun} (it has {evidence(root, kind, 2)}{_INSTEAD[kind]})"


def _toml_table(path: Path) -> Table | None:
    """``path`` read as TOML; None when it is not TOML (or too large to be ours)."""
    try:
        if path.stat().st_size > _TOML_READ_LIMIT:
            return None
        return parse_toml(path.read_text(encoding="utf-8"), str(path))
    except (OSError, UnicodeDecodeError, ConfigError):
        return None
