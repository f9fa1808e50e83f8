"""FCL as a peer: python-fcl's dynamic AABB tree on the inflated spheres (optional)."""

from __future__ import annotations

from typing import Any

import numpy as np

from dua_mujoco.experiments.peers.ghost_world import GhostTrajectory, pair_id
from dua_mujoco.experiments.peers.horizon import InflatedGhost

__all__ = ["FclGhost", "fcl_available"]


def fcl_available() -> bool:
    """Whether python-fcl can be imported (``pip install python-fcl``)."""
    try:
        import fcl  # noqa: F401
    except ImportError:
        return False
    return True


class FclGhost(InflatedGhost):
    """python-fcl's DynamicAABBTree on the inflated spheres (``GhostPeer``).

    python-fcl exposes no batch update: radii and translations are set one object at a time and
    candidates come back through a Python callback, so this measures FCL *through its Python
    binding* (an upper bound on the C++ library's cost).
    """

    name = "FCL"
    note = "DynamicAABBTreeCollisionManager via python-fcl (per-object Python calls)"

    def __init__(self, world: GhostTrajectory) -> None:
        import fcl

        super().__init__(world)
        self.fcl = fcl
        self.geoms = [fcl.Sphere(float(r)) for r in world.radius]
        self.objs = [fcl.CollisionObject(g, fcl.Transform(np.zeros(3))) for g in self.geoms]
        self.index = {id(g): i for i, g in enumerate(self.geoms)}
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects(self.objs)
        self.manager.setup()
        self.request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)

    def _alarms(self, c: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, int]:
        fcl = self.fcl
        grown = self._grown(v)
        for g, o, r, p in zip(self.geoms, self.objs, grown.tolist(), c, strict=True):
            g.radius = r
            g.computeLocalAABB()  # without it the tree keeps the old AABB
            o.setTranslation(p)
        self.manager.update()
        data = fcl.CollisionData(request=fcl.CollisionRequest(num_max_contacts=10**7))
        count = [0]

        def callback(o1: Any, o2: Any, cdata: Any) -> bool:
            count[0] += 1
            return bool(fcl.defaultCollisionCallback(o1, o2, cdata))

        self.manager.collide(data, callback)
        contacts = data.result.contacts
        if not contacts:
            return np.zeros(0, dtype=np.int64), count[0]
        idx = np.array(
            [(self.index[id(ct.o1)], self.index[id(ct.o2)]) for ct in contacts], dtype=np.int64
        )
        return np.unique(pair_id(idx[:, 0], idx[:, 1], self.n)), count[0]
