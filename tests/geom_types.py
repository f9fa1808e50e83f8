"""One geom of each type the covering and the exact geometry take, for the tests that run over
every type: MJCF attributes by type name (sizes 0.04 to 0.25 m), and the asset of the random
convex mesh ``blob`` that the ``"mesh"`` one names."""

from __future__ import annotations

import numpy as np

GEOM_TYPES = {
    "sphere": 'type="sphere" size=".12"',
    "capsule": 'type="capsule" size=".05 .2"',
    "ellipsoid": 'type="ellipsoid" size=".2 .06 .1"',
    "cylinder": 'type="cylinder" size=".1 .15"',
    "box": 'type="box" size=".25 .1 .04"',
    "mesh": 'type="mesh" mesh="blob"',
}

_BLOB = (np.random.default_rng(7).normal(size=(24, 3)) * [0.2, 0.1, 0.07]).ravel()
BLOB_ASSET = f'<asset><mesh name="blob" vertex="{" ".join(f"{x:.4f}" for x in _BLOB)}"/></asset>'
"""The ``<asset>`` element of ``blob``: 24 random points about 0.2 x 0.1 x 0.07 m (their hull)."""
