"""Cache keys for compiled kernels that call compiled functions of other modules.

numba checks a kernel cached on disk (``cache=True``) against its own source file only, but the cached
machine code holds the compiled functions it calls from other modules too: an edit to one of those
would leave the kernel running the old code until its cache is cleared. A closure variable's value is
part of numba's cache key, so such a kernel is built by a factory that closes over
``sources_fingerprint`` of the modules it reaches; an edit to any of them compiles it afresh.
``tests/navigator/test_kernel_cache_keys.py`` checks that every cached kernel reaching another module's
compiled functions carries the fingerprint of exactly those modules.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from types import ModuleType


def sources_fingerprint(*modules: ModuleType) -> str:
    """sha256 of the modules' source files, in module-name order (so the order given does not matter)."""
    digest = hashlib.sha256()
    for module in sorted(modules, key=lambda m: m.__name__):
        digest.update(Path(str(module.__file__)).read_bytes())
    return digest.hexdigest()
