"""Pelvis orientation in OpenSim's convention, in any simulator world.

OpenSim's pelvis angles (``pelvis_tilt``, ``pelvis_list``, ``pelvis_rotation``) are body-fixed
rotations about Z, X and Y of a frame that is X forward, Y up and Z right. A simulator world
names its own up and forward axes (gait2d: Y up; MyoLeg: Z up, both X forward); its right is
forward x up. :func:`opensim_to_world` maps the one frame onto the other.
"""

from __future__ import annotations

from functools import cache

import numpy as np


@cache
def opensim_to_world(up_axis: int, forward_axis: int) -> np.ndarray:
    """[3, 3] rotation taking OpenSim-frame vectors (X forward, Y up, Z right) to the
    simulator's world (columns: where forward, up and right point); read-only, cached."""
    forward, up = np.eye(3)[forward_axis], np.eye(3)[up_axis]
    out = np.column_stack([forward, up, np.cross(forward, up)])
    out.flags.writeable = False
    return out


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pelvis_rotation(
    pitch: float, list_: float, rotation: float, up_axis: int, forward_axis: int
) -> np.ndarray:
    """[3, 3] world-from-pelvis rotation of a pelvis at OpenSim angles (rad); the pelvis's own
    frame is OpenSim-style (its X forward, Y up, Z right), as in gait2d and MyoLeg."""
    return opensim_to_world(up_axis, forward_axis) @ _rz(pitch) @ _rx(list_) @ _ry(rotation)


def pelvis_pitch_list(
    pelvis_up: np.ndarray, up_axis: int, forward_axis: int
) -> tuple[float, float]:
    """OpenSim pelvis tilt and list (rad) of a pelvis whose up axis points along
    ``pelvis_up`` ([3], world). Exact for Z-X-Y angles: the up axis does not depend on the
    last rotation (``pelvis_rotation``)."""
    c = opensim_to_world(up_axis, forward_axis)
    x, y, z = c.T @ np.asarray(pelvis_up, float)  # (-sin t cos l, cos t cos l, sin l)
    return float(np.arctan2(-x, y)), float(np.arcsin(np.clip(z, -1.0, 1.0)))


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of two [3] vectors, written out: numpy's ``cross`` costs more than a
    control step can spare (its result, operation for operation, is the same)."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def pelvis_frame(pelvis_up: np.ndarray, pelvis_forward: np.ndarray) -> np.ndarray:
    """[3, 3] world-from-pelvis rotation (columns: the pelvis's forward, up and right axes in
    the world) of a pelvis whose up and forward axes point along ``pelvis_up`` and
    ``pelvis_forward`` ([3], world, unit, orthogonal)."""
    forward, up = np.asarray(pelvis_forward, float), np.asarray(pelvis_up, float)
    return np.column_stack([forward, up, cross3(forward, up)])


def turn_about_up(start: np.ndarray, end: np.ndarray, up_axis: int) -> float:
    """The angle (rad, in (-pi, pi], positive counter-clockwise seen from above) by which a
    frame turned about the world's up axis from ``start`` to ``end`` ([3, 3] world-from-body
    rotations, :func:`pelvis_frame`): the twist of the relative rotation about the vertical,
    whatever it tipped besides. A rotation about a horizontal axis only, which is all a planar
    pelvis can do, turns by exactly 0."""
    rel = np.asarray(end, float) @ np.asarray(start, float).T
    # rel - rel.T = 2 sin(angle) [axis]_x and 1 + trace = 4 cos^2(angle / 2): their ratio
    # along the up axis is tan of half the twist
    axial = (rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1])[up_axis]
    return float(2.0 * np.arctan2(axial, 1.0 + np.trace(rel)))
