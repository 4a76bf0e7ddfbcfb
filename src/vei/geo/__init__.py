"""Geodesy: the local world frame, ego-relative <-> world, geographic bounds."""

from vei.geo.frame import Bounds, LocalFrame, wrap_angle

__all__ = ["Bounds", "LocalFrame", "wrap_angle"]
