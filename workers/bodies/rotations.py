"""Rotations as the body schema writes them: body-fixed X-Y-Z Euler angles (OpenSim's frame
``orientation``) and axis-angle turns, as 3x3 matrices."""

from __future__ import annotations

import math

import numpy as np


def rotation_xyz(angles: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """Rotation matrix of body-fixed X-Y-Z Euler angles (rad): ``Rx(a) @ Ry(b) @ Rz(c)``."""
    a, b, c = (float(v) for v in angles)
    return axis_rotation((1, 0, 0), a) @ axis_rotation((0, 1, 0), b) @ axis_rotation((0, 0, 1), c)


def euler_xyz(r: np.ndarray) -> tuple[float, float, float]:
    """Body-fixed X-Y-Z Euler angles (rad) of rotation matrix ``r`` (the inverse of
    :func:`rotation_xyz`)."""
    b = math.asin(max(-1.0, min(1.0, float(r[0, 2]))))
    return (math.atan2(-r[1, 2], r[2, 2]), b, math.atan2(-r[0, 1], r[0, 0]))


def axis_rotation(axis: tuple[float, float, float] | np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about ``axis`` (any length) by ``angle`` (rad), Rodrigues."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
