"""MuJoCo's dynamic pair filter as one compiled rule, for given candidate pairs or over all pairs.

The rule is ``filter.py``'s list of dynamic-pair conditions (``filterBodyPair``,
``filterBitmask``, ``<exclude>``, the collision-function table), written once as ``_rule``.
The kernels apply it to candidate geom pairs (what a pruned predictor meets, O(candidates), as
MuJoCo's own broadphase applies it), to every geom pair of a small model (the all-pairs
predictor), to count the pairs of a large model without holding them (O(ngeom) memory, for the
report's fractions), and to find whether any pair passes. Explicit ``<pair>`` elements are
``filter.py``'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numba as nb
import numpy as np
import numpy.typing as npt

from dua_mujoco.mj.geom_types import GEOM_HFIELD, GEOM_PLANE

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
def _rule(b1, w1, p1, m1, c1, a1, l1, b2, w2, p2, m2, c2, a2, l2, exclude, filterparent):
    """MuJoCo's dynamic filter for two geoms, given by their bodies ``b``, weld groups ``w``,
    weld parents ``p``, mobility ``m``, contype ``c``, conaffinity ``a`` and plane/height
    field ``l`` (scalars: the pair loops load the first geom's once per row)."""
    if b1 == b2 or w1 == w2:  # one body, or welded together (static-static: both 0)
        return False
    if not (m1 or m2):
        return False
    if filterparent and w1 != 0 and w2 != 0 and (w1 == p2 or w2 == p1):
        return False
    if (c1 & a2) == 0 and (c2 & a1) == 0:
        return False
    if l1 and l2:
        return False
    if exclude.shape[0]:
        signature = (min(b1, b2) << 16) + max(b1, b2)
        i = np.searchsorted(exclude, signature)
        if i < exclude.shape[0] and exclude[i] == signature:
            return False
    return True


@nb.njit(cache=True, inline="always")
def _ok(g1, g2, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    return _rule(
        body[g1], weld[g1], parent_weld[g1], movable[g1], contype[g1], conaff[g1], lone[g1],
        body[g2], weld[g2], parent_weld[g2], movable[g2], contype[g2], conaff[g2], lone[g2],
        exclude, filterparent,
    )  # fmt: skip


@nb.njit(cache=True)
def _mask(g1, g2, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    out = np.zeros(g1.shape[0], dtype=np.bool_)
    for k in range(g1.shape[0]):
        a, b = g1[k], g2[k]
        out[k] = a != b and _ok(
            a, b, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent
        )
    return out


@nb.njit(cache=True)
def _row(i, out, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    """Mark in ``out[j]`` (j > i) which pairs (i, j) pass; their count."""
    b1, w1, p1, m1 = body[i], weld[i], parent_weld[i], movable[i]
    c1, a1, l1 = contype[i], conaff[i], lone[i]
    c = 0
    for j in range(i + 1, body.shape[0]):
        ok = _rule(
            b1, w1, p1, m1, c1, a1, l1,
            body[j], weld[j], parent_weld[j], movable[j], contype[j], conaff[j], lone[j],
            exclude, filterparent,
        )  # fmt: skip
        out[j] = ok
        c += ok
    return c


@nb.njit(cache=True)
def _all_pairs(body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    n = body.shape[0]
    row = np.zeros(n, dtype=np.bool_)
    count = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):  # two passes: the pairs are held once, in their final arrays
        c = _row(i, row, body, weld, parent_weld, movable, contype, conaff, lone, exclude,
                 filterparent)  # fmt: skip
        count[i + 1] = count[i] + c
    g1 = np.empty(count[n], dtype=np.int64)
    g2 = np.empty(count[n], dtype=np.int64)
    for i in range(n):
        _row(i, row, body, weld, parent_weld, movable, contype, conaff, lone, exclude,
             filterparent)  # fmt: skip
        k = count[i]
        for j in range(i + 1, n):
            if row[j]:
                g1[k] = i
                g2[k] = j
                k += 1
    return g1, g2


@nb.njit(cache=True)
def _count(weight, body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    n = body.shape[0]
    row = np.zeros(n, dtype=np.bool_)
    pairs = 0
    weighted = 0
    for i in range(n):
        pairs += _row(i, row, body, weld, parent_weld, movable, contype, conaff, lone, exclude,
                      filterparent)  # fmt: skip
        w = 0
        for j in range(i + 1, n):
            if row[j]:
                w += weight[j]
        weighted += weight[i] * w
    return pairs, weighted


@nb.njit(cache=True)
def _any(body, weld, parent_weld, movable, contype, conaff, lone, exclude, filterparent):
    n = body.shape[0]
    row = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if _row(i, row, body, weld, parent_weld, movable, contype, conaff, lone, exclude,
                filterparent):  # fmt: skip
            return True
    return False


def any_dynamic_pair(tables: FilterTables) -> bool:
    """Whether the dynamic filter lets any geom pair through (stops at the first)."""
    return bool(_any(*tables.args()))


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
