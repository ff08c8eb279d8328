"""Where numba keeps its compiled kernels when the places it looks for itself are read-only.

The kernels are ``@numba.njit(cache=True)``. numba caches next to the source (``__pycache__``) or, failing
that, in the user's cache (``$XDG_CACHE_HOME/numba``, else ``~/.cache/numba``); when neither is writable
(installed read-only under /opt, run by a service user without a home) the decorator raises at import,
and ``rover run`` died before its first line. So, before any kernel is imported, the ``rover`` entry point
points ``NUMBA_CACHE_DIR`` at a directory of ours when numba would find none. An operator's own
``NUMBA_CACHE_DIR`` (``deploy/rover.service`` sets one) is always kept.
"""

from __future__ import annotations

import importlib.util
import os
import stat
import tempfile
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

# The packages that hold cached kernels (rover_cli itself holds none).
KERNEL_PACKAGES = ("estimator", "hil", "navigator")


@dataclass(frozen=True)
class CacheChoice:
    """A directory for ``NUMBA_CACHE_DIR`` and why numba's own places would not do."""

    path: Path
    reason: str


def can_write(directory: Path) -> bool:
    """Whether numba could cache in ``directory``: the test numba itself makes (create it, write a file)."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
    except OSError:
        return False
    return True


def user_cache_dir(environ: Mapping[str, str]) -> Path:
    """numba's user-wide cache on Linux (appdirs): ``$XDG_CACHE_HOME/numba``, else ``~/.cache/numba``."""
    base = environ.get("XDG_CACHE_HOME") or str(Path(environ.get("HOME", "~")).expanduser() / ".cache")
    return Path(base) / "numba"


def choose_numba_cache_dir(
    environ: Mapping[str, str],
    package_dirs: Iterable[Path],
    fallback: Callable[[], Path],
    writable: Callable[[Path], bool] = can_write,
) -> CacheChoice | None:
    """The directory to set as ``NUMBA_CACHE_DIR``, or None to leave numba to its own choice.

    None when the operator set ``NUMBA_CACHE_DIR``, or when numba can cache in every kernel package's
    ``__pycache__`` or, failing any of those, in the user's cache (``user_cache_dir``). Otherwise
    what ``fallback`` makes (``private_temp_cache``), called only then.
    """
    if environ.get("NUMBA_CACHE_DIR"):
        return None
    not_in_tree = [d for d in package_dirs if not writable(d / "__pycache__")]
    if not not_in_tree:
        return None
    user_wide = user_cache_dir(environ)
    if writable(user_wide):
        return None
    return CacheChoice(
        fallback(),
        f"{not_in_tree[0] / '__pycache__'} and {user_wide} are not writable",
    )


def private_temp_cache(temp_dir: Path, uid: int) -> Path:
    """``<temp>/rover-numba-cache-<uid>`` if it is ours alone, else a fresh private directory.

    numba's cache files are pickles loaded as code: a directory another user made (or can write) in a
    shared /tmp could hand us theirs, so such a directory is not used (a fresh one costs a cold compile).
    """
    path = temp_dir / f"rover-numba-cache-{uid}"
    try:
        path.mkdir(mode=0o700, exist_ok=True)
        info = path.lstat()
    except OSError:
        return Path(tempfile.mkdtemp(prefix="rover-numba-cache-", dir=temp_dir))
    private = (
        stat.S_ISDIR(info.st_mode) and info.st_uid == uid and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)
    )
    if private:
        return path
    return Path(tempfile.mkdtemp(prefix="rover-numba-cache-", dir=temp_dir))


def kernel_package_dirs() -> list[Path]:
    """The directories of the packages with cached kernels, found without importing them."""
    dirs: list[Path] = []
    for name in KERNEL_PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.submodule_search_locations:
            dirs.extend(Path(location) for location in spec.submodule_search_locations)
    return dirs


def ensure_numba_cache(environ: dict[str, str] | None = None) -> CacheChoice | None:
    """Set ``NUMBA_CACHE_DIR`` in ``environ`` (default ``os.environ``) if numba would find nowhere to
    cache; returns what was set (for the caller to log), or None. Call before numba is imported: numba
    reads the variable once, on import."""
    env = os.environ if environ is None else environ
    try:
        choice = choose_numba_cache_dir(
            env, kernel_package_dirs(), lambda: private_temp_cache(Path(tempfile.gettempdir()), os.getuid())
        )
    except OSError:  # not even the temp directory is writable: numba's own error will say so
        return None
    if choice is not None:
        env["NUMBA_CACHE_DIR"] = str(choice.path)
    return choice
