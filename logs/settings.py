"""Strict reading of TOML settings: every error names the file, the key and what was wrong.

Both kinds of file (rover config, scenario) are read through ``Table``; each package turns the tables it
owns into frozen dataclasses with a ``from_table`` constructor. Unknown keys are errors, so a typo never
silently falls back to a default.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

# The largest seed anything takes: TOML's largest integer, so a seed from the command line can always be
# written into a scenario file and read back (``rover hil soak`` writes its seed into the scenario it
# generates). numpy's generators take any integer >= 0, so this is the tighter of the two bounds.
MAX_SEED = 2**63 - 1


class ConfigError(ValueError):
    """A settings file is missing, malformed, or holds a value we cannot use."""

    def __init__(self, source: str, key: str, problem: str) -> None:
        self.source = source
        self.key = key
        self.problem = problem
        where = f"{source}: {key}" if key else source
        super().__init__(f"{where}: {problem}")


def load_toml(path: str | Path) -> Table:
    """Read a TOML file into a root ``Table``; raises ``ConfigError`` naming the file on any failure."""
    return parse_toml(read_settings_text(path), str(path))


def read_settings_text(path: str | Path) -> str:
    """A settings file's text, for a caller that keeps it as well as parsing it (a scenario is recorded as
    written); raises ``ConfigError`` naming the file when it cannot be read."""
    source = str(path)
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(source, "", "file not found") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(source, "", f"cannot read file: {err}") from err


def parse_toml(text: str, source: str) -> Table:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(source, "", f"not valid TOML: {err}") from err
    return Table(data, source, "")


class Table:
    """A TOML table with typed, range-checked getters. Call ``finish()`` to reject unknown keys."""

    def __init__(self, data: dict[str, Any], source: str, prefix: str) -> None:
        self._data = data
        self.source = source
        self.prefix = prefix
        self._used: set[str] = set()
        # Keys asked about with ``has()``: optional keys read only when present. Known keys all the same,
        # so a typo of one is named by ``finish()`` (a key present but never read is still unknown).
        self._asked: set[str] = set()

    # --- helpers -------------------------------------------------------------------------------
    def key_path(self, key: str) -> str:
        """``key`` under this table's path; "" is the table itself."""
        if not key:
            return self.prefix
        return f"{self.prefix}.{key}" if self.prefix else key

    def error(self, key: str, problem: str) -> ConfigError:
        return ConfigError(self.source, self.key_path(key), problem)

    def absent(self, key: str, problem: str) -> ConfigError:
        """``problem``: ``key`` is missing ("" for something of this table, read only when present: a layer
        file, a class table); but a key written here one slip from the one missing (from any known one
        for "") is named first, as unknown. The typo is the likelier cause, and a message about the key
        meant never names it ("radius_m: required key is missing" when ``raduis_m`` is written)."""
        meant = [key] if key else sorted(self._used | self._asked)
        # Not read nor asked about yet, and a near miss only, not finish()'s looser match: a key not read yet
        # may be a real one read later, and two real keys differ by more (yield_max_m and yield_max_s
        # differ by one letter, but neither is ever missing: both have defaults).
        for written in sorted(set(self._data) - self._used - self._asked):
            near = next((k for k in meant if near_miss(written, k)), None)
            if near is not None:
                where = f"{self.key_path(key)}: " if self.key_path(key) else ""
                return ConfigError(
                    self.source,
                    self.key_path(written),
                    f"unknown key (did you mean {near!r}? without it: {where}{problem})",
                )
        return self.error(key, problem)

    def has(self, key: str) -> bool:
        self._asked.add(key)
        return key in self._data

    def keys(self) -> Iterator[str]:
        return iter(self._data)

    def _raw(self, key: str, default: Any) -> Any:
        self._used.add(key)
        if key in self._data:
            return self._data[key]
        if default is _REQUIRED:
            raise self.absent(key, "required key is missing")
        return default

    # --- typed getters -------------------------------------------------------------------------
    def number(
        self, key: str, default: Any = None, *, lo: float | None = None, hi: float | None = None
    ) -> float:
        value = self._raw(key, _REQUIRED if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"expected a number, got {type(value).__name__} {value!r}")
        number = finite_float(value)
        if number is None:
            raise self.error(key, f"expected a finite number, got {shown(value)}")
        if lo is not None and number < lo:
            raise self.error(key, f"must be >= {lo}, got {number}")
        if hi is not None and number > hi:
            raise self.error(key, f"must be <= {hi}, got {number}")
        return number

    def integer(self, key: str, default: Any = None, *, lo: int | None = None, hi: int | None = None) -> int:
        value = self._raw(key, _REQUIRED if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {type(value).__name__} {value!r}")
        if lo is not None and value < lo:
            raise self.error(key, f"must be >= {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.error(key, f"must be <= {hi}, got {value}")
        return value

    def text(self, key: str, default: Any = None, *, choices: Sequence[str] | None = None) -> str:
        value = self._raw(key, _REQUIRED if default is None else default)
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {type(value).__name__} {value!r}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(map(repr, choices))}, got {value!r}")
        return value

    def flag(self, key: str, default: Any = None) -> bool:
        value = self._raw(key, _REQUIRED if default is None else default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {value!r}")
        return value

    def point(self, key: str, default: Any = None) -> tuple[float, float]:
        """An ``[x, y]`` pair of finite numbers."""
        value = self._raw(key, _REQUIRED if default is None else default)
        numbers = [finite_float(v) for v in value] if isinstance(value, list | tuple) else []
        if len(numbers) != 2 or None in numbers:
            raise self.error(key, f"expected [x, y] with two finite numbers, got {shown(value)}")
        return float(value[0]), float(value[1])

    def numbers(self, key: str, default: Any = None, *, length: int | None = None) -> list[float]:
        value = self._raw(key, _REQUIRED if default is None else default)
        if not isinstance(value, list) or any(finite_float(v) is None for v in value):
            raise self.error(key, f"expected a list of finite numbers, got {shown(value)}")
        if length is not None and len(value) != length:
            raise self.error(key, f"expected {length} numbers, got {len(value)}")
        return [float(v) for v in value]

    def integers(self, key: str, default: Any = None, *, length: int | None = None) -> list[int]:
        value = self._raw(key, _REQUIRED if default is None else default)
        if not isinstance(value, list) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        ):
            raise self.error(key, f"expected a list of integers, got {value!r}")
        if length is not None and len(value) != length:
            raise self.error(key, f"expected {length} integers, got {len(value)}")
        return list(value)

    def table(self, key: str, *, optional: bool = False) -> Table:
        """A sub-table; with ``optional`` a missing one reads as empty (all defaults)."""
        value = self._raw(key, {} if optional else _REQUIRED)
        if not isinstance(value, dict):
            raise self.error(key, f"expected a table, got {type(value).__name__}")
        return Table(value, self.source, self.key_path(key))

    def tables(self, key: str, *, optional: bool = True) -> list[Table]:
        """An array of tables (``[[key]]``)."""
        value = self._raw(key, [] if optional else _REQUIRED)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(key, "expected an array of tables ([[...]])")
        return [Table(v, self.source, f"{self.key_path(key)}[{i}]") for i, v in enumerate(value)]

    def file_path(self, key: str, base_dir: Path, what: str) -> Path:
        """The existing file ``key`` names, read relative to ``base_dir`` (the folder of the file the table
        is in). A file that is not there is an error saying where it was looked for, and, when the path
        exists from the current directory instead, that this is the mix-up: a person writes the path from
        where they stand, not from the config's folder. ``what`` names the file in that error."""
        written = self.text(key)
        path = base_dir / written
        if path.exists():
            return path
        problem = (
            f"{what} {written!r} not found: a relative path is read from the folder of "
            f"{self.source} ({base_dir.resolve()}), which gives {path}"
        )
        if not Path(written).is_absolute() and Path(written).exists():
            problem += (
                f"; {written!r} exists from the current directory ({Path(written).resolve()}): write that "
                "absolute path, or one relative to the config's folder"
            )
        raise self.error(key, problem)

    def raw(self, key: str, default: Any = None) -> Any:
        """The value as TOML gave it, for callers that validate it themselves."""
        return self._raw(key, _REQUIRED if default is None else default)

    def finish(self) -> None:
        """Reject keys nobody asked for: they are typos or settings this version does not know."""
        unknown = sorted(set(self._data) - self._used)
        if unknown:
            key = unknown[0]
            # A typo is the usual cause: name the nearest known key first, then all of them.
            known = sorted(self._used | self._asked)
            problem = f"unknown key ({did_you_mean(key, known)}known here: {', '.join(known) or 'none'})"
            # No setting has a dot in its name: this is a quoted dotted key, which reads as the real one.
            if "." in key:
                table, _, leaf = key.rpartition(".")
                problem += (
                    f"; TOML read {key!r} (quoted) as one key with a dot in its name: write it unquoted, "
                    f"{key} = ..., to set {leaf} in [{self.key_path(table)}]"
                )
            raise self.error(key, problem)


def did_you_mean(written: str, known: Sequence[str]) -> str:
    """``"did you mean 'x'? "`` naming the known key nearest to ``written``, or "" when none is near."""
    # difflib misses a slip in a short key ("di" for "id"): a one-slip match as well.
    nearest = (
        difflib.get_close_matches(written, known, n=1, cutoff=0.6)
        or [k for k in known if near_miss(written, k)][:1]
    )
    return f"did you mean {nearest[0]!r}? " if nearest else ""


# Unit suffixes of our keys: a key written without its unit (radius for radius_m) is the key meant.
_UNIT_SUFFIXES = frozenset({"m", "s", "ms", "ns", "deg", "rad", "hz", "mps", "mps2", "rps", "pct", "v", "a"})


def near_miss(written: str, meant: str) -> bool:
    """``written`` is ``meant`` with one slip (``_one_slip``), in other letter case (XY for xy), or without
    its unit suffix (radius for radius_m, resolution for resolution_m): the likely typos of a key."""
    if written == meant:
        return False
    if written.lower() == meant.lower() or _one_slip(written, meant):
        return True
    stem, _, unit = meant.rpartition("_")
    return unit in _UNIT_SUFFIXES and written.lower() == stem.lower()


def _one_slip(written: str, meant: str) -> bool:
    """``written`` is ``meant`` with one letter left out, added or changed, or two neighbours swapped."""
    if written == meant or abs(len(written) - len(meant)) > 1:
        return False
    if len(written) == len(meant):
        differ = [i for i, (a, b) in enumerate(zip(written, meant, strict=True)) if a != b]
        swapped = (
            len(differ) == 2
            and differ[1] == differ[0] + 1
            and written[differ[0]] == meant[differ[1]]
            and written[differ[1]] == meant[differ[0]]
        )
        return len(differ) == 1 or swapped
    shorter, longer = sorted((written, meant), key=len)
    return any(longer[:i] + longer[i + 1 :] == shorter for i in range(len(longer)))


def finite_float(value: Any) -> float | None:
    """``value`` as a finite float, or None when it is no number (a bool is not) or has no finite float:
    NaN, inf, or an integer too large for one (TOML parses any number of digits; float() would raise)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def shown(value: Any) -> str:
    """``repr`` of a value for an error, with an integer of hundreds of digits cut to its length."""
    text = repr(value)
    return text if len(text) <= 80 else f"{text[:40]}... ({len(text)} characters)"


class _Required:
    def __repr__(self) -> str:
        return "<required>"


_REQUIRED: Any = _Required()
