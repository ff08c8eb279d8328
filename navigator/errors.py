"""The navigator's error family: one base, then parameter/terrain (setup) and planning (operation) errors."""

from __future__ import annotations


class NavigatorError(Exception):
    """Base of every error the navigator raises on purpose."""


class ParameterError(NavigatorError, ValueError):
    """A parameter or input value is outside the range the navigator can use (vehicle, follower, commands)."""


class TerrainError(NavigatorError, ValueError):
    """A terrain map or a query on it is unusable (bad layers, unknown class, point off the map)."""


class PlanningError(NavigatorError):
    """A plan cannot be made as asked (start or goal off the map or inside a lethal cell)."""


class NoPathError(PlanningError):
    """Start and goal are both valid but no traversable path connects them."""
