"""The navigator's error family: one base, then parameter/terrain (setup) and planning (operation) errors."""

from __future__ import annotations


class NavigatorError(Exception):
    """Base of every error the navigator raises on purpose."""


class ParameterError(NavigatorError, ValueError):
    """A parameter or input value is outside the range the navigator can use (vehicle, follower, commands)."""


class TerrainError(NavigatorError, ValueError):
    """A terrain map or a query on it is unusable (bad layers, unknown class, point off the map).

    ``key``: the map table's key the problem is in (a layer: "elevation", "classes", "obstacles"), when
    known, so a config error can name it."""

    def __init__(self, message: str, *, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


class PlanningError(NavigatorError):
    """A plan cannot be made as asked (start or goal off the map or inside a lethal cell)."""


class NoPathError(PlanningError):
    """Start and goal are both valid but no traversable path connects them."""
