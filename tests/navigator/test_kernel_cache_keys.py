"""Every cached kernel that compiles in code or constants of another module of ours carries the
fingerprint of those modules' sources in numba's cache key (``navigator.kernel_cache``), so an edit
there cannot leave it running stale cached code."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path
from types import CodeType, ModuleType

import numba.core.registry

from navigator.kernel_cache import sources_fingerprint

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("estimator", "firmware_bridge", "hil", "logs", "navigator")
Dispatcher = numba.core.registry.CPUDispatcher


def _kernel_modules() -> list[ModuleType]:
    return [
        importlib.import_module(f"{package}.{path.stem}")
        for package in PACKAGES
        for path in sorted((ROOT / package).glob("*.py"))
        if "numba" in path.read_text()
    ]


def _imported_from(module: ModuleType) -> dict[str, str]:
    """Each name the module imports from one of our modules (``from X import name``) -> X."""
    tree = ast.parse(Path(str(module.__file__)).read_text())
    return {
        alias.asname or alias.name: node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PACKAGES
        for alias in node.names
    }


def _names(code: CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, CodeType):
            names |= _names(const)
    return names


def _reached(kernel: Dispatcher, seen: set[int] | None = None) -> set[str]:
    """The modules whose code or constants ``kernel`` compiles in, its own included, through the
    compiled functions it calls."""
    seen = set() if seen is None else seen
    seen.add(id(kernel))
    own = kernel.py_func.__module__
    module = importlib.import_module(own)
    imported = _imported_from(module)
    reached = {own}
    for name in _names(kernel.py_func.__code__):
        value = vars(module).get(name)
        if isinstance(value, ModuleType) and value.__name__.split(".")[0] in PACKAGES:
            reached.add(value.__name__)
        elif name in imported:
            reached.add(imported[name])
        if isinstance(value, Dispatcher) and id(value) not in seen:
            reached |= _reached(value, seen)
    return reached


def _cached_kernels(module: ModuleType) -> list[Dispatcher]:
    return [
        value
        for value in vars(module).values()
        if isinstance(value, Dispatcher)
        and value.py_func.__module__ == module.__name__
        and type(getattr(value, "_cache", None)).__name__ != "NullCache"
    ]


def test_cached_kernels_carry_the_fingerprint_of_every_other_module_they_compile_in():
    checked = 0
    for module in _kernel_modules():
        for kernel in _cached_kernels(module):
            others = _reached(kernel) - {module.__name__}
            if not others:
                continue
            cells = [cell.cell_contents for cell in kernel.py_func.__closure__ or ()]
            expected = sources_fingerprint(*(importlib.import_module(name) for name in others))
            assert expected in cells, (
                f"{module.__name__}.{kernel.py_func.__name__} compiles in {sorted(others)} but its cache key "
                "does not carry their sources' fingerprint (navigator.kernel_cache)"
            )
            checked += 1
    assert checked >= 4  # the dynamics step, the plan repair and the two cost-to-go fields at least


def test_the_fingerprint_changes_with_any_source_and_not_with_the_order():
    from navigator import astar_bucket_kernel, astar_kernel

    both = sources_fingerprint(astar_kernel, astar_bucket_kernel)
    assert both == sources_fingerprint(astar_bucket_kernel, astar_kernel)
    assert both != sources_fingerprint(astar_kernel)
