"""The native core's pair-table kernels (``csrc/src/pairs.cc``) as the Python layer calls them.

One implementation each, which the MuJoCo plugin's pruned pairs also run when they learn a pair:
the expansion of geom pairs into sphere pairs (``filter.sphere_pairs``), MuJoCo's margin and gap
of a dynamic geom pair (``filter``), the summed bounds of a pair (``pairbounds``) and the exact
level's records (``exact``). Callers validate; these only convert and call.
"""

from __future__ import annotations

import ctypes
import functools
from typing import Any

import numpy as np
import numpy.typing as npt

from dua_mujoco.mj.exact_kernels import X_NCOL
from dua_mujoco.native import declare

__all__ = ["contact_params", "exact_rows", "expand", "pair_bounds"]

_P, _I8 = ctypes.c_void_p, ctypes.c_int64


@functools.cache
def _lib() -> Any:
    """The kernels, their signatures declared once."""
    return declare(
        {
            "dua_sphere_pairs": (_I8, [_P, _P, _P, _P, _I8, _P, _P, _P, _P, _I8, *[_P] * 5]),
            "dua_contact_distance": (None, [_P, _P, _P, _P, _I8, _I8, ctypes.c_double, _P, _P]),
            "dua_pair_bounds": (None, [_P, _P, _P, _I8, _P, _P, _P, _P, _P, _P, _P]),
            "dua_exact_rows": (None, [_P, _P, _P, _P, _P, _I8, _P]),
        }
    )


def _c(a: npt.ArrayLike, dtype: type) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=dtype)


def expand(
    g1: npt.ArrayLike,
    g2: npt.ArrayLike,
    dist: npt.ArrayLike,
    index: npt.ArrayLike,
    start: npt.ArrayLike,
    geom_plane: npt.ArrayLike,
    geom_shape: npt.ArrayLike,
    radius: npt.ArrayLike,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sphere pairs of geom pairs ``(g1[k], g2[k])`` (``dua_sphere_pairs``): ``(first,
    second, kind, geom_pair, eps)``, ``(n,)`` each, grouped by geom pair."""
    ins = [
        _c(a, t)
        for a, t in (
            (g1, np.int64), (g2, np.int64), (dist, np.float64), (index, np.int64),
            (start, np.int64), (geom_plane, np.int64), (geom_shape, np.int64),
            (radius, np.float64),
        )
    ]  # fmt: skip
    ptr = [a.ctypes.data for a in ins]
    ngp = ins[0].shape[0]
    fn = _lib().dua_sphere_pairs
    total = int(fn(*ptr[:4], ngp, *ptr[4:], 0, None, None, None, None, None))
    first, second, geom_pair = (np.empty(total, dtype=np.int64) for _ in range(3))
    kind = np.empty(total, dtype=np.int8)
    eps = np.empty(total)
    outs = [a.ctypes.data for a in (first, second, kind, geom_pair, eps)]
    fn(*ptr[:4], ngp, *ptr[4:], total, *outs)
    return first, second, kind, geom_pair, eps


def contact_params(
    gmargin: npt.ArrayLike,
    ggap: npt.ArrayLike,
    g1: npt.ArrayLike,
    g2: npt.ArrayLike,
    o_margin: float | None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(margin, gap)`` MuJoCo gives the dynamic geom pairs ``(g1[k], g2[k])``; ``o_margin``:
    the override's margin, or None without ``mjENBL_OVERRIDE``."""
    a, b = _c(g1, np.int64), _c(g2, np.int64)
    gm, gg = _c(gmargin, np.float64), _c(ggap, np.float64)
    margin, gap = np.empty(a.shape[0]), np.empty(a.shape[0])
    _lib().dua_contact_distance(
        gm.ctypes.data, gg.ctypes.data, a.ctypes.data, b.ctypes.data, a.shape[0],
        int(o_margin is not None), 0.0 if o_margin is None else float(o_margin),
        margin.ctypes.data, gap.ctypes.data,
    )  # fmt: skip
    return margin, gap


def pair_bounds(
    first: npt.ArrayLike,
    second: npt.ArrayLike,
    kind: npt.ArrayLike,
    sphere_body: npt.ArrayLike,
    accel: npt.ArrayLike,
    delta: npt.ArrayLike,
    speed: npt.ArrayLike | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each pair's summed ``(accel, delta, speed)`` from its bodies' (``dua_pair_bounds``; a
    plane or static shape is the world body's; ``speed`` None: inf)."""
    f, s, sb = _c(first, np.int64), _c(second, np.int64), _c(sphere_body, np.int64)
    k = _c(kind, np.int8)
    a, d = _c(accel, np.float64), _c(delta, np.float64)
    v = None if speed is None else _c(speed, np.float64)
    n = k.shape[0]
    out = np.empty(n), np.empty(n), np.empty(n)
    _lib().dua_pair_bounds(
        f.ctypes.data, s.ctypes.data, k.ctypes.data, n, sb.ctypes.data, a.ctypes.data,
        d.ctypes.data, None if v is None else v.ctypes.data, *(o.ctypes.data for o in out),
    )  # fmt: skip
    return out


def exact_rows(
    geoms: npt.ArrayLike,
    geom1: npt.ArrayLike,
    geom2: npt.ArrayLike,
    kind: npt.ArrayLike,
    dist: npt.ArrayLike,
) -> np.ndarray:
    """``(n, X_NCOL)`` exact-level records of pairs over per-geom records ``geoms``
    (``dua_exact_rows``)."""
    g1, g2, k = _c(geom1, np.int64), _c(geom2, np.int64), _c(kind, np.int8)
    d = _c(np.broadcast_to(dist, g1.shape), np.float64)
    table = _c(geoms, np.float64)
    rec = np.zeros((g1.shape[0], X_NCOL))
    _lib().dua_exact_rows(
        table.ctypes.data, g1.ctypes.data, g2.ctypes.data, k.ctypes.data, d.ctypes.data,
        g1.shape[0], rec.ctypes.data,
    )  # fmt: skip
    return rec
