"""MuJoCo's dynamic pair filter as one native rule, for given candidate pairs or over all pairs.

The rule is ``filter.py``'s list of dynamic-pair conditions (``filterBodyPair``,
``filterBitmask``, ``<exclude>``, the collision-function table), written once in the native core
(``csrc/src/filter.cc``). It is applied to candidate geom pairs (what a pruned predictor meets,
O(candidates), as MuJoCo's own broadphase applies it), to every geom pair of a small model (the
all-pairs predictor), to count the pairs of a large model without holding them (O(ngeom)
memory, for the report's fractions), and to find whether any pair passes. Explicit ``<pair>``
elements are ``filter.py``'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.geom_types import GEOM_HFIELD, GEOM_PLANE

__all__ = [
    "FilterTables",
    "all_dynamic_pairs",
    "any_dynamic_pair",
    "count_dynamic_pairs",
    "dynamic_mask",
]


@dataclass(frozen=True)
class FilterTables:
    """Per geom, what the dynamic filter reads (``FilterTables.of(model)``).

    Attributes:
        body: ``(ngeom,)`` geom body.
        weld: ``(ngeom,)`` weld group of each geom's body.
        parent_weld: ``(ngeom,)`` weld group of the parent of that body's weld root.
        movable: ``(ngeom,)`` whether that weld group has degrees of freedom.
        contype: ``(ngeom,)``.
        conaffinity: ``(ngeom,)``.
        lone: ``(ngeom,)`` plane or height field (no collision function between two of them).
        exclude: ``(nexclude,)`` sorted ``<exclude>`` body-pair signatures.
        filterparent: The parent filter is on (no ``mjDSBL_FILTERPARENT``).
    """

    body: np.ndarray
    weld: np.ndarray
    parent_weld: np.ndarray
    movable: np.ndarray
    contype: np.ndarray
    conaffinity: np.ndarray
    lone: np.ndarray
    exclude: np.ndarray
    filterparent: bool
    _native: _core.Filter = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        def held(name: str, dtype: type = np.int64) -> Any:
            value: np.ndarray = np.ascontiguousarray(getattr(self, name), dtype=dtype)
            object.__setattr__(self, name, value)
            return value

        u8 = np.uint8
        native = _core.Filter(
            held("body"), held("weld"), held("parent_weld"), held("movable", u8), held("contype"),
            held("conaffinity"), held("lone", u8), held("exclude"), bool(self.filterparent),
        )  # fmt: skip
        object.__setattr__(self, "_native", native)

    @classmethod
    def of(cls, model: mujoco.MjModel) -> FilterTables:
        """The tables of ``model``."""
        weld = np.asarray(model.body_weldid, dtype=np.int64)
        parent = np.asarray(model.body_parentid, dtype=np.int64)
        types = np.asarray(model.geom_type, dtype=np.int64)
        flags = int(model.opt.disableflags)
        body = np.asarray(model.geom_bodyid, dtype=np.int64)
        # Per geom, not per body: one lookup less in the pair loop.
        return cls(
            body=body,
            weld=weld[body],
            parent_weld=weld[parent[weld]][body],
            # Weld roots are the world, mocap bodies and bodies with joints; only the latter
            # have dofs (MuJoCo 4.0 skips pairs where neither weld group has any).
            movable=(np.asarray(model.body_dofnum, dtype=np.int64)[weld] > 0)[body],
            contype=np.asarray(model.geom_contype, dtype=np.int64),
            conaffinity=np.asarray(model.geom_conaffinity, dtype=np.int64),
            lone=np.isin(types, (GEOM_PLANE, GEOM_HFIELD)),
            exclude=np.sort(np.asarray(model.exclude_signature, dtype=np.int64)),
            filterparent=not flags & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT),
        )


def any_dynamic_pair(tables: FilterTables) -> bool:
    """Whether the dynamic filter lets any geom pair through (stops at the first)."""
    return bool(tables._native.any())


def dynamic_mask(tables: FilterTables, g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
    """``(n,)`` bool: which geom pairs ``(g1[k], g2[k])`` MuJoCo's dynamic filter lets through
    (O(n); a geom with itself never)."""
    a = np.asarray(g1, dtype=np.int64).reshape(-1)
    b = np.asarray(g2, dtype=np.int64).reshape(-1)
    return np.asarray(tables._native.mask(a, b))


def all_dynamic_pairs(tables: FilterTables) -> tuple[np.ndarray, np.ndarray]:
    """Every geom pair ``g1 < g2`` the dynamic filter lets through, sorted (O(ngeom^2) time,
    O(result) memory: counted first, then written)."""
    g1, g2 = tables._native.all()
    return np.asarray(g1), np.asarray(g2)


def count_dynamic_pairs(tables: FilterTables, weight: npt.ArrayLike) -> tuple[int, int]:
    """How many geom pairs the dynamic filter lets through, and the sum over them of
    ``weight[g1] * weight[g2]`` (O(ngeom^2) time, nothing held)."""
    pairs, weighted = tables._native.count(np.asarray(weight, dtype=np.int64))
    return int(pairs), int(weighted)
