"""MuJoCo's collision filter -> active geom pairs -> sphere pairs.

``active_geom_pairs`` reproduces, for a compiled model, the geom pairs MuJoCo 4.0's
``mj_collision`` can ever pass to a narrow-phase function, with the margin and gap it uses for
each (a pair's contact distance is ``margin + gap``): the geometry-independent filters exactly,
rule by rule with their place in MuJoCo's C source in docs/covering-and-pairs.md. The geometric
prunes (sweep-and-prune, BVH mid-phase, bounding spheres) are what collision prediction replaces;
runtime-only filters (sleeping islands, ``mjcb_contactfilter``) only remove pairs, so the set is
a superset of what they let through.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, fields

import mujoco
import numpy as np
import numpy.typing as npt

from dua_mujoco import _core
from dua_mujoco.build.covering import Covering
from dua_mujoco.build.geom_types import GEOM_HFIELD, GEOM_PLANE
from dua_mujoco.build.pairfilter import FilterTables, all_dynamic_pairs, dynamic_mask
from dua_mujoco.core.pairset import PairKind
from dua_mujoco.exceptions import InvalidChoiceError, InvalidInputError, UnsupportedGeomError

__all__ = [
    "GeomPairs",
    "SpherePairs",
    "active_geom_pairs",
    "body_id",
    "candidate_geom_pairs",
    "contact_distance_bound",
    "contacts_enabled",
    "explicit_geom_pairs",
    "margin_override",
    "pairs_between_bodies",
    "sphere_pair_mask",
    "sphere_pairs",
]


@dataclass(frozen=True)
class GeomPairs:
    """The geom pairs MuJoCo can collide: sorted by ``(geom1, geom2)`` as
    :func:`active_geom_pairs` builds them; a pruned predictor appends the pairs it meets
    (:meth:`concat`), so an index, once given, names the same pair for good.

    Attributes:
        geom1: ``(npair,)`` int32, first geom (``geom1 < geom2``).
        geom2: ``(npair,)`` int32, second geom.
        explicit: ``(npair,)`` bool, the pair comes from a ``<pair>`` element.
        margin: ``(npair,)`` float64, the margin MuJoCo uses for the pair (force threshold).
        gap: ``(npair,)`` float64, the gap MuJoCo uses for the pair.
        contact_distance: ``(npair,)`` float64, ``margin + gap``: MuJoCo reports a contact in
            ``d.contact`` when the signed distance of the two geoms is at most this.
    """

    geom1: np.ndarray
    geom2: np.ndarray
    explicit: np.ndarray
    margin: np.ndarray
    gap: np.ndarray
    contact_distance: np.ndarray
    _keys: np.ndarray = field(init=False, repr=False, compare=False)
    _order: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        keys = _pair_keys(self.geom1, self.geom2)
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
        if keys.size > 1 and not np.all(keys[1:] > keys[:-1]):
            raise InvalidInputError(
                "GeomPairs must hold each (geom1, geom2) once; build it with "
                "active_geom_pairs(model)."
            )
        object.__setattr__(self, "_keys", keys)
        object.__setattr__(self, "_order", order)

    @property
    def npair(self) -> int:
        """Number of active geom pairs."""
        return int(self.geom1.shape[0])

    def __len__(self) -> int:
        return self.npair

    def concat(self, other: GeomPairs) -> GeomPairs:
        """These pairs, then ``other``'s (none of them among these)."""
        init = [f.name for f in fields(self) if f.init]
        return GeomPairs(*(np.concatenate([getattr(self, n), getattr(other, n)]) for n in init))

    def index_of(self, g1: int, g2: int) -> int:
        """Index of the geom pair ``{g1, g2}`` (either order), or -1 if it is not active."""
        return int(self.indices_of([g1], [g2])[0])

    def indices_of(self, g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
        """Indices of the geom pairs ``{g1[k], g2[k]}`` (either order): ``(n,)`` int64, -1 where
        not active."""
        a = np.asarray(g1, dtype=np.int64).reshape(-1)
        b = np.asarray(g2, dtype=np.int64).reshape(-1)
        keys = _pair_keys(np.minimum(a, b), np.maximum(a, b))
        if self.npair == 0:
            return np.full(keys.shape, -1, dtype=np.int64)
        i = np.minimum(np.searchsorted(self._keys, keys), self._keys.shape[0] - 1)
        return np.where(self._keys[i] == keys, self._order[i], -1).astype(np.int64)


def _pair_keys(g1: npt.ArrayLike, g2: npt.ArrayLike) -> np.ndarray:
    return (np.asarray(g1, dtype=np.int64) << 32) | np.asarray(g2, dtype=np.int64)


def _disabled(model: mujoco.MjModel, flag: mujoco.mjtDisableBit) -> bool:
    return bool(int(model.opt.disableflags) & int(flag))


def _empty() -> GeomPairs:
    return GeomPairs(
        geom1=np.zeros(0, np.int32),
        geom2=np.zeros(0, np.int32),
        explicit=np.zeros(0, bool),
        margin=np.zeros(0),
        gap=np.zeros(0),
        contact_distance=np.zeros(0),
    )


def contacts_enabled(model: mujoco.MjModel) -> bool:
    """False when no pair can ever collide (contacts or constraints disabled, one body)."""
    return not (
        _disabled(model, mujoco.mjtDisableBit.mjDSBL_CONTACT)
        or _disabled(model, mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        or int(model.nbody) + int(model.nflex) < 2
        or int(model.ngeom) < 1
    )


def active_geom_pairs(model: mujoco.MjModel) -> GeomPairs:
    """The geom pairs MuJoCo 4.0 can ever collide, with their margin, gap and contact distance.

    Every geom pair is put to the dynamic filter in one compiled pass (``pairfilter``), then the
    explicit ``<pair>`` elements are merged in. O(ngeom^2) time: a pruned predictor filters only
    the candidates it meets (:func:`candidate_geom_pairs`). Sorted by ``(geom1, geom2)``.
    """
    if not contacts_enabled(model):
        return _empty()
    g1, g2 = all_dynamic_pairs(FilterTables.of(model))
    return _with_explicit(model, g1, g2, explicit=True)


def explicit_geom_pairs(model: mujoco.MjModel) -> GeomPairs:
    """The geom pairs of the ``<pair>`` elements, as :func:`active_geom_pairs` has them (with
    the dynamic pair of the same geoms where MuJoCo collides both: the larger distance)."""
    if not contacts_enabled(model) or not int(model.npair):
        return _empty()
    p1 = np.asarray(model.pair_geom1, dtype=np.int64)
    p2 = np.asarray(model.pair_geom2, dtype=np.int64)
    lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
    twin = dynamic_mask(FilterTables.of(model), lo, hi)
    keys = np.unique(_pair_keys(lo[twin], hi[twin]))
    return _with_explicit(model, keys >> 32, keys & 0xFFFFFFFF, explicit=True)


def candidate_geom_pairs(
    model: mujoco.MjModel, tables: FilterTables, g1: npt.ArrayLike, g2: npt.ArrayLike
) -> GeomPairs:
    """Of candidate geom pairs (no key twice, none of a ``<pair>``'s geoms: those are
    :func:`explicit_geom_pairs`), the ones MuJoCo's dynamic filter lets through, as
    :func:`active_geom_pairs` has them. O(candidates)."""
    a = np.asarray(g1, dtype=np.int64)
    b = np.asarray(g2, dtype=np.int64)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keep = dynamic_mask(tables, lo, hi) if contacts_enabled(model) else np.zeros(a.size, bool)
    return _with_explicit(model, lo[keep], hi[keep], explicit=False)  # it sorts them


def _with_explicit(
    model: mujoco.MjModel, g1: np.ndarray, g2: np.ndarray, *, explicit: bool
) -> GeomPairs:
    """Dynamic pairs ``g1 < g2`` with their margin and gap, and (``explicit``) the ``<pair>``
    elements merged in."""
    types = np.asarray(model.geom_type, dtype=np.int64)
    gbody = np.asarray(model.geom_bodyid, dtype=np.int64)
    gmargin = np.asarray(model.geom_margin, dtype=np.float64)
    ggap = np.asarray(model.geom_gap, dtype=np.float64)
    g1 = np.asarray(g1, dtype=np.int64)
    g2 = np.asarray(g2, dtype=np.int64)
    b1, b2 = gbody[g1], gbody[g2]
    signature = (np.minimum(b1, b2) << 16) + np.maximum(b1, b2)

    # --- explicit pairs: merged in, replacing the dynamic pair with the same signature and geoms
    npair = int(model.npair) if explicit else 0
    if npair:
        p1 = np.asarray(model.pair_geom1, dtype=np.int64)
        p2 = np.asarray(model.pair_geom2, dtype=np.int64)
        psig = np.asarray(model.pair_signature, dtype=np.int64)
        lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
        # A dynamic pair is replaced only when the explicit pair has the same geoms and the same
        # body-pair signature (filterCollisionPair's `merged` scan over pair_signature).
        dyn_keys, keys = _pair_keys(g1, g2), _pair_keys(lo, hi)
        explicit_sigs = set(zip(keys.tolist(), psig.tolist(), strict=True))
        candidates = np.flatnonzero(np.isin(dyn_keys, keys))
        merged = np.zeros(g1.shape[0], dtype=bool)
        merged[candidates] = [
            (int(dyn_keys[i]), int(signature[i])) in explicit_sigs for i in candidates
        ]
        g1, g2 = g1[~merged], g2[~merged]
        pmargin = np.asarray(model.pair_margin, dtype=np.float64)
        pgap = np.asarray(model.pair_gap, dtype=np.float64)
        # Where mjCOLLISIONFUNC has an entry: not plane-plane, plane-hfield, hfield-hfield.
        lone = np.isin(types, (GEOM_PLANE, GEOM_HFIELD))
        valid = ~(lone[lo] & lone[hi])
        lo, hi, pmargin, pgap = lo[valid], hi[valid], pmargin[valid], pgap[valid]
    else:
        lo = hi = np.zeros(0, np.int64)
        pmargin = pgap = np.zeros(0)

    o_margin = margin_override(model)
    # The native core's rule (a pruned predictor's runtime gives the pairs it meets the same).
    dyn_margin, dyn_gap = _core.contact_distance(
        gmargin, ggap, g1, g2, o_margin is not None, 0.0 if o_margin is None else o_margin
    )
    all1 = np.concatenate([g1, lo])
    all2 = np.concatenate([g2, hi])
    is_explicit = np.concatenate([np.zeros(g1.shape[0], bool), np.ones(lo.shape[0], bool)])
    explicit_margin = pmargin if o_margin is None else np.full_like(pmargin, o_margin)
    margin = np.concatenate([dyn_margin, explicit_margin])
    gap = np.concatenate([dyn_gap, pgap])
    dist = margin + gap

    # Sort by key; where one geom pair appears twice (a <pair> whose signature does not match the
    # dynamic pair, or repeated <pair> elements) MuJoCo collides it twice: keep the larger
    # contact distance, which is the one that reports contacts first.
    keys = _pair_keys(all1, all2)
    order = np.lexsort((-dist, keys))
    keys = keys[order]
    first = np.ones(keys.shape[0], dtype=bool)
    first[1:] = keys[1:] != keys[:-1]
    sel = order[first]
    return GeomPairs(
        geom1=all1[sel].astype(np.int32),
        geom2=all2[sel].astype(np.int32),
        explicit=is_explicit[sel],
        margin=margin[sel],
        gap=gap[sel],
        contact_distance=dist[sel],
    )


def margin_override(model: mujoco.MjModel) -> float | None:
    """The margin every pair takes under ``mjENBL_OVERRIDE`` (``opt.o_margin``), or None."""
    if int(model.opt.enableflags) & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE):
        return float(model.opt.o_margin)
    return None


def contact_distance_bound(model: mujoco.MjModel, explicit: GeomPairs) -> float:
    """The largest contact distance (margin + gap) any geom pair of ``model`` can have
    (``explicit``: its :func:`explicit_geom_pairs`)."""
    gmargin = np.asarray(model.geom_margin, dtype=np.float64)
    ggap = np.asarray(model.geom_gap, dtype=np.float64)
    o_margin = margin_override(model)
    top_margin = 2 * float(gmargin.max(initial=0.0)) if o_margin is None else o_margin
    bound = top_margin + 2 * float(ggap.max(initial=0.0))
    return max(0.0, bound, float(explicit.contact_distance.max(initial=0.0)))


@dataclass(frozen=True)
class SpherePairs:
    """Sphere-sphere, sphere-half-space and sphere-static-shape pairs of the active geom pairs.

    Attributes:
        first: ``(n,)`` int32 sphere id.
        second: ``(n,)`` int32 sphere id, or plane index (into ``Covering.plane_geom``) where
            ``is_halfspace``, or shape index (into ``Covering.shape_geom``) where ``is_shape``.
        is_halfspace: ``(n,)`` bool.
        geom_pair: ``(n,)`` int32 index into the :class:`GeomPairs` it came from.
        eps: ``(n,)`` float64 contact distance of the sphere pair: ``r1 + r2 + d`` for two spheres,
            ``r + d`` for a sphere and a half-space or a static shape, ``d`` the geom pair's
            contact distance.
        is_shape: ``(n,)`` bool (all False when omitted).
    """

    first: np.ndarray
    second: np.ndarray
    is_halfspace: np.ndarray
    geom_pair: np.ndarray
    eps: np.ndarray
    is_shape: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def __post_init__(self) -> None:
        if self.is_shape.shape != self.first.shape:
            object.__setattr__(self, "is_shape", np.zeros(self.first.shape, dtype=bool))

    @property
    def kind(self) -> np.ndarray:
        """``(n,)`` int8 ``dua_mujoco.core.pairset.PairKind`` codes."""
        out = np.zeros(self.first.shape, dtype=np.int8)
        out[self.is_halfspace] = int(PairKind.HALFSPACE)
        out[self.is_shape] = int(PairKind.SHAPE)
        return out

    @property
    def npair(self) -> int:
        """Number of sphere pairs."""
        return int(self.first.shape[0])

    def __len__(self) -> int:
        return self.npair


def sphere_pairs(covering: Covering, geom_pairs: GeomPairs) -> SpherePairs:
    """Expand active geom pairs into sphere pairs (every sphere of one geom x every of the other).

    A geom held as a half-space (plane) or a static shape pairs as that one object with every
    sphere of the other geom. Pairs of two planes are dropped (MuJoCo has no plane-plane
    collider). A plane geom must be static (welded to the world): only then is it a fixed
    half-space. ``covering`` and ``geom_pairs`` are of the same model.

    Returns:
        The :class:`SpherePairs`, grouped by geom pair in ``geom_pairs`` order.

    Raises:
        UnsupportedGeomError: a plane in an active pair is not static, a geom in an active pair
            has no spheres, or an active pair has no sphere at all (a static shape with a plane
            or another shape).
    """
    gp1 = np.asarray(geom_pairs.geom1, dtype=np.int64)
    gp2 = np.asarray(geom_pairs.geom2, dtype=np.int64)
    if gp1.size and max(int(gp1.max()), int(gp2.max())) >= covering.ngeom:
        raise InvalidInputError(
            "geom_pairs refers to geoms the covering does not have: build both from the same model."
        )
    plane1 = covering.geom_plane[gp1] >= 0
    plane2 = covering.geom_plane[gp2] >= 0
    moving = ~covering.plane_static
    for gp, is_plane in ((gp1, plane1), (gp2, plane2)):
        bad = gp[is_plane][moving[covering.geom_plane[gp[is_plane]]]]
        if bad.size:
            g = int(bad[0])
            raise UnsupportedGeomError(
                f"plane geom {g} is in an active pair but its body is not welded to the world "
                "(e.g. a mocap body): only static planes are supported as half-spaces. Attach "
                "the plane to the world body, or replace it by a large thin box."
            )
    keep = ~(plane1 & plane2)
    idx = np.flatnonzero(keep)
    gp1, gp2, plane1, plane2 = gp1[idx], gp2[idx], plane1[idx], plane2[idx]
    shape1 = covering.geom_shape[gp1] >= 0
    shape2 = covering.geom_shape[gp2] >= 0
    lone1 = plane1 | shape1  # held as one object, not spheres
    lone2 = plane2 | shape2
    both = np.flatnonzero(lone1 & lone2)
    if both.size:
        g, h = int(gp1[both[0]]), int(gp2[both[0]])
        raise UnsupportedGeomError(
            f"geoms {g} and {h} form an active pair but neither has spheres (a static shape "
            "with a plane or another static shape): build the covering with cover_model, which "
            "keeps spheres for static geoms in such <pair> elements."
        )
    halfspace = plane1 | plane2
    shape = shape1 | shape2
    # Put the sphere-covered geom first for half-space and shape pairs.
    ga = np.where(lone1, gp2, gp1)
    gb = np.where(lone1, gp1, gp2)
    start = covering.geom_sphere_start.astype(np.int64)
    na = start[ga + 1] - start[ga]
    single = halfspace | shape
    nb = np.where(single, 1, start[gb + 1] - start[gb])
    bad_geom = np.concatenate([ga[na == 0], gb[~single & (nb == 0)]])
    if bad_geom.size:
        g = int(bad_geom[0])
        raise UnsupportedGeomError(
            f"geom {g} is in an active pair but has no covering spheres; build the covering with "
            "cover_model(model, only_collidable=True) from the same model as the pairs."
        )
    # The expansion is the native core's (the plugin's pruned pairs expand the pairs they meet
    # with it too).
    dist = np.asarray(geom_pairs.contact_distance, dtype=np.float64)[idx]
    first, second, kind, geom_pair, eps = _core.sphere_pairs(
        np.asarray(gp1, dtype=np.int64), np.asarray(gp2, dtype=np.int64), dist,
        np.asarray(idx, dtype=np.int64), start, np.asarray(covering.geom_plane, dtype=np.int64),
        np.asarray(covering.geom_shape, dtype=np.int64), covering.sphere_radius,
    )  # fmt: skip
    return SpherePairs(
        first=first.astype(np.int32),
        second=second.astype(np.int32),
        is_halfspace=kind == int(PairKind.HALFSPACE),
        geom_pair=geom_pair.astype(np.int32),
        eps=eps,
        is_shape=kind == int(PairKind.SHAPE),
    )


def body_id(model: mujoco.MjModel, body: int | str) -> int:
    if isinstance(body, str):
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        if bid < 0:
            names = (model.body(b).name for b in range(model.nbody))
            raise InvalidChoiceError("body", body, [n for n in names if n])
        return int(bid)
    if isinstance(body, bool) or not isinstance(body, int | np.integer):
        raise InvalidInputError(f"a body is given by name or id, got {body!r}.")
    if not 0 <= int(body) < model.nbody:
        raise InvalidInputError(
            f"body id {body!r} is out of range: the model has {model.nbody} bodies."
        )
    return int(body)


def pairs_between_bodies(
    model: mujoco.MjModel, geom_pairs: GeomPairs, body_a: int | str, body_b: int | str | None = None
) -> np.ndarray:
    """Indices of the active geom pairs ``geom_pairs`` with one geom on ``body_a`` and the other on
    ``body_b`` (names or ids; ``body_b`` None: every pair involving ``body_a``).

    Returns:
        ``(k,)`` int64 indices into ``geom_pairs``, increasing.

    Raises:
        InvalidChoiceError: unknown body name (the message lists the body names).
        InvalidInputError: body id out of range.
    """
    a = body_id(model, body_a)
    gbody = np.asarray(model.geom_bodyid, dtype=np.int64)
    ba = gbody[np.asarray(geom_pairs.geom1, dtype=np.int64)]
    bb = gbody[np.asarray(geom_pairs.geom2, dtype=np.int64)]
    if body_b is None:
        mask = (ba == a) | (bb == a)
    else:
        b = body_id(model, body_b)
        mask = ((ba == a) & (bb == b)) | ((ba == b) & (bb == a))
    return np.flatnonzero(mask).astype(np.int64)


def sphere_pair_mask(
    sphere_pairs: SpherePairs, geom_pair_indices: npt.ArrayLike | Iterable[int]
) -> np.ndarray:
    """``(n,)`` bool over ``sphere_pairs``: those of the geom pairs ``geom_pair_indices``,
    ``(k,)`` indices into the :class:`GeomPairs` they were built from."""
    idx = geom_pair_indices
    if isinstance(idx, Iterable) and not isinstance(idx, np.ndarray):
        idx = np.asarray(list(idx), dtype=np.int64)
    return np.isin(sphere_pairs.geom_pair, np.asarray(idx, dtype=np.int64).reshape(-1))
