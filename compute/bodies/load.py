"""What drives a step from outside the bodies."""

from __future__ import annotations

from typing import NamedTuple


class Load(NamedTuple):
    """``pressure`` on the walls (pressure control) or their inward ``wall_speed`` (velocity
    control); ``gravity`` (2,) acceleration of every body."""

    pressure: float
    wall_speed: float
    gravity: tuple[float, float]
