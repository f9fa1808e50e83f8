"""MuJoCo's dynamic pair filter as one compiled rule, for given candidate pairs or over all pairs.

The rule is ``filter.py``'s list of dynamic-pair conditions (``filterBodyPair``,
``filterBitmask``, ``<exclude>``, the collision-function table), written once as
:func:`_dynamic_ok`. Three kernels apply it: to candidate geom pairs (what a pruned predictor
meets, O(candidates), as MuJoCo's own broadphase applies it), to every geom pair of a small
model (the all-pairs predictor), and to count the pairs of a large model without holding them
(O(ngeom) memory, for the report's fractions). Explicit ``<pair>`` elements are ``filter.py``'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.mj.geom_types import GEOM_HFIELD, GEOM_PLANE

__all__ = ["FilterTables", "all_dynamic_pairs", "count_dynamic_pairs", "dynamic_mask"]


@dataclass(frozen=True)
class FilterTables:
    """Per geom and per body, what the dynamic filter reads (``filter_tables(model)``).

    Attributes:
        body: ``(ngeom,)`` geom body.
        weld: ``(nbody,)`` weld group of each body.
        parent_weld: ``(nbody,)`` weld group of the parent of each body's weld root.
        movable: ``(nbody,)`` whether the body's weld group has degrees of freedom.
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

    @classmethod
    def of(cls, model: mujoco.MjModel) -> FilterTables:
        """The tables of ``model``."""
        weld = np.asarray(model.body_weldid, dtype=np.int64)
        parent = np.asarray(model.body_parentid, dtype=np.int64)
        types = np.asarray(model.geom_type, dtype=np.int64)
        flags = int(model.opt.disableflags)
        return cls(
            body=np.asarray(model.geom_bodyid, dtype=np.int64),
            weld=weld,
            parent_weld=weld[parent[weld]],
            # Weld roots are the world, mocap bodies and bodies with joints; only the latter
            # have dofs (MuJoCo 4.0 skips pairs where neither weld group has any).
            movable=np.asarray(model.body_dofnum, dtype=np.int64)[weld] > 0,
            contype=np.asarray(model.geom_contype, dtype=np.int64),
            conaffinity=np.asarray(model.geom_conaffinity, dtype=np.int64),
            lone=np.isin(types, (GEOM_PLANE, GEOM_HFIELD)),
            exclude=np.sort(np.asarray(model.exclude_signature, dtype=np.int64)),
            filterparent=not flags & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT),
        )

    def args(self) -> tuple:
        return (
            self.body,
            self.weld,
            self.parent_weld,
            self.movable,
            self.contype,
            self.conaffinity,
            self.lone,
            self.exclude,
            self.filterparent,
        )


@nb.njit(cache=True, inline="always")
def _dynamic_ok(
    g1, g2, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
):
    """MuJoCo's dynamic filter for geoms ``g1 != g2`` (either order)."""
    b1, b2 = body[g1], body[g2]
    w1, w2 = weld[b1], weld[b2]
    if b1 == b2 or w1 == w2:  # one body, or welded together (static-static: both 0)
        return False
    if not (movable[b1] or movable[b2]):
        return False
    if filterparent and w1 != 0 and w2 != 0 and (w1 == parent_weld[b2] or w2 == parent_weld[b1]):
        return False
    if (contype[g1] & conaff[g2]) == 0 and (contype[g2] & conaff[g1]) == 0:
        return False
    if lone[g1] and lone[g2]:
        return False
    if exclude.shape[0]:
        signature = (min(b1, b2) << 16) + max(b1, b2)
        i = np.searchsorted(exclude, signature)
        if i < exclude.shape[0] and exclude[i] == signature:
            return False
    return True


@nb.njit(cache=True)
def _mask(g1, g2, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    out = np.zeros(g1.shape[0], dtype=np.bool_)
    for k in range(g1.shape[0]):
        a, b = g1[k], g2[k]
        out[k] = a != b and _dynamic_ok(
            a, b, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
        )
    return out


@nb.njit(cache=True)
def _all_pairs(body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    n = body.shape[0]
    count = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):  # two passes: the pairs are held once, in their final arrays
        c = 0
        for j in range(i + 1, n):
            c += _dynamic_ok(
                i, j, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
            )
        count[i + 1] = count[i] + c
    g1 = np.empty(count[n], dtype=np.int64)
    g2 = np.empty(count[n], dtype=np.int64)
    for i in range(n):
        k = count[i]
        for j in range(i + 1, n):
            if _dynamic_ok(
                i, j, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
            ):
                g1[k] = i
                g2[k] = j
                k += 1
    return g1, g2


@nb.njit(cache=True)
def _count(weight, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    n = body.shape[0]
    pairs = 0
    weighted = 0
    for i in range(n):
        for j in range(i + 1, n):
            if _dynamic_ok(
                i, j, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
            ):
                pairs += 1
                weighted += weight[i] * weight[j]
    return pairs, weighted


def dynamic_mask(tables: FilterTables, g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
    """``(n,)`` bool: which geom pairs ``(g1[k], g2[k])`` MuJoCo's dynamic filter lets through
    (O(n); a geom with itself never)."""
    a = np.ascontiguousarray(g1, dtype=np.int64)
    b = np.ascontiguousarray(g2, dtype=np.int64)
    return _mask(a, b, *tables.args())


def all_dynamic_pairs(tables: FilterTables) -> tuple[np.ndarray, np.ndarray]:
    """Every geom pair ``g1 < g2`` the dynamic filter lets through, sorted (O(ngeom^2) time,
    O(result) memory)."""
    return _all_pairs(*tables.args())


def count_dynamic_pairs(tables: FilterTables, weight: npt.ArrayLike) -> tuple[int, int]:
    """How many geom pairs the dynamic filter lets through, and the sum over them of
    ``weight[g1] * weight[g2]`` (O(ngeom^2) time, nothing held)."""
    w = np.ascontiguousarray(weight, dtype=np.int64)
    pairs, weighted = _count(w, *tables.args())
    return int(pairs), int(weighted)
