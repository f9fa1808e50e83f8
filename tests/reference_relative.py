"""A slow reference of the relative deviation (docs/theory.md, Lemma 8.2d), for the tests.

Body ``b``'s box corners, in the frame of a geom of body ``a``, at the actual relative pose
``T_a^-1 T_b`` against the planned one ``P_a^-1 P_b``: the largest distance between the two
places of a corner. Written from the definition (4x4 homogeneous transforms, an explicit inverse),
not from the runtime's formulas.
"""

from __future__ import annotations

import itertools

import numpy as np


def transform(pos: np.ndarray, mat: np.ndarray) -> np.ndarray:
    """The 4x4 homogeneous transform of a pose (position (3,), row-major rotation (9,))."""
    t = np.eye(4)
    t[:3, :3] = np.asarray(mat).reshape(3, 3)
    t[:3, 3] = pos
    return t


def corners(center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """``(8, 3)`` a box's corners."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    return np.asarray(center) + signs * np.asarray(half)


def relative_deviation(
    center: np.ndarray,
    half: np.ndarray,
    actual_a: tuple[np.ndarray, np.ndarray],
    actual_b: tuple[np.ndarray, np.ndarray],
    planned_a: tuple[np.ndarray, np.ndarray],
    planned_b: tuple[np.ndarray, np.ndarray],
) -> float:
    """The largest distance, over the corners of b's box (in b's frame), between the corner's
    place in a's frame at the actual poses and at the planned ones."""
    q = np.hstack([corners(center, half), np.ones((8, 1))]).T  # (4, 8)
    actual = np.linalg.inv(transform(*actual_a)) @ transform(*actual_b) @ q
    planned = np.linalg.inv(transform(*planned_a)) @ transform(*planned_b) @ q
    return float(np.linalg.norm(actual[:3] - planned[:3], axis=0).max())
