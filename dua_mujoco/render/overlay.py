"""``AlarmOverlay``: alarms drawn into a MuJoCo scene (offscreen frames or the live viewer).

Pure red lines between the spheres of each pair standing in alarm (pure red is theirs alone, for
pixel tests), a tint of the geoms of standing pairs by tau (brick red, orange, yellow; static
geoms never), translucent covering spheres (``show_spheres``); docs/rendering.md has the
colours. The live viewer's own scene of the model's geoms is not reachable, so there the lines
and spheres go into ``viewer.user_scn`` (:meth:`AlarmOverlay.add_to_user_scn`) and the tint into
the model's ``geom_rgba`` (:meth:`AlarmOverlay.tint_rgba`); ``dua_mujoco.render.live.LiveViewer``
does both (``dua-mujoco view``).
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import mujoco
import numpy as np

from dua_mujoco.build.covering import sphere_world_centers
from dua_mujoco.build.geom_types import GEOM_LINE, GEOM_PLANE, GEOM_SPHERE
from dua_mujoco.core.pairset import PairKind
from dua_mujoco.core.shapes import closest_point
from dua_mujoco.exceptions import InvalidInputError
from dua_mujoco.runtime.alarms import Alarms
from dua_mujoco.runtime.predictor import Predictor

__all__ = [
    "ALARM_RGBA",
    "SPHERE_RGB",
    "TINTS",
    "URGENCY_LEVELS",
    "AlarmOverlay",
    "OverlayOptions",
    "SceneFullWarning",
]

ALARM_RGBA = (1.0, 0.0, 0.0, 1.0)
"""Colour of alarm connectors, reserved: nothing else the overlay draws is pure red."""

URGENCY_LEVELS = (2.0, 8.0, np.inf)
"""Upper bounds, in predictor periods, of the tau of a geom's most urgent *alarmed* pair for the
tints imminent, near, alarmed (geoms without an alarmed pair keep their own colour)."""

TINTS = np.array([[0.9, 0.3, 0.2], [1.0, 0.55, 0.1], [0.95, 0.85, 0.25]], dtype=np.float32)
"""``(3, 3)`` RGB of the levels imminent, near, alarmed."""

SPHERE_RGB = (0.3, 0.7, 1.0)
"""Colour of covering spheres whose geom stands in no alarm."""

_OBJ_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_OBJ_UNKNOWN = int(mujoco.mjtObj.mjOBJ_UNKNOWN)
_CAT_DECOR = int(mujoco.mjtCatBit.mjCAT_DECOR)
_EYE = np.eye(3).ravel()
_ZERO3 = np.zeros(3)


class SceneFullWarning(UserWarning):
    """The ``MjvScene`` had no room left (``maxgeom``): some overlay geoms were not drawn."""


@dataclasses.dataclass(frozen=True)
class OverlayOptions:
    """What :class:`AlarmOverlay` draws.

    Attributes:
        show_spheres: Draw the covering spheres (one scene geom per sphere).
        sphere_alpha: Opacity of the covering spheres, in ``(0, 1]``.
        tint_geoms: Recolour model geoms by urgency (in the live viewer through the model's
            ``geom_rgba``; see module docstring).
        connectors: Draw a pure red line for each alarmed sphere pair.
        text: Stamp a status line (time, alarms, misses) on rendered frames.
        connector_width: Width of connector lines in pixels (``mjGEOM_LINE`` widths are pixels).
    """

    show_spheres: bool = False
    sphere_alpha: float = 0.25
    tint_geoms: bool = True
    connectors: bool = True
    text: bool = True
    connector_width: float = 3.0

    def __post_init__(self) -> None:
        if not 0.0 < self.sphere_alpha <= 1.0:
            raise InvalidInputError(
                f"sphere_alpha = {self.sphere_alpha!r} is invalid: it must be in (0, 1]."
            )
        if not self.connector_width > 0.0:
            raise InvalidInputError(
                f"connector_width = {self.connector_width!r} is invalid: it must be > 0 pixels."
            )


class AlarmOverlay:
    """Adds a predictor's alarms to an ``MjvScene`` (offscreen renderer or live viewer).

    Args:
        predictor: The predictor whose alarms and scheduler state are drawn.
        options: What to draw.

    Attributes:
        dropped: Overlay geoms dropped so far because the scene was full.
        standing: ``(k,)`` the sphere pairs standing in alarm at the latest
            :meth:`add_to_scene` (what it tinted and connected).
    """

    def __init__(self, predictor: Predictor, *, options: OverlayOptions = OverlayOptions()) -> None:
        self.predictor = predictor
        self.options = options
        self.dropped = 0
        self.standing = np.zeros(0, dtype=np.int64)
        self._warned = False
        model = predictor.model
        self._read_tables()
        # The world (floors, tables, walls) is never tinted: a red table says nothing a red link
        # standing on it does not, and it would flood the frame. Their pairs tint the other geom.
        welded = np.asarray(model.body_weldid)[np.asarray(model.geom_bodyid)] == 0
        self._tintable = (np.asarray(model.geom_type) != GEOM_PLANE) & ~welded

    def _read_tables(self) -> None:
        """The predictor's pair tables as they stand (a pruned predictor learns pairs as it
        runs: read again when it has)."""
        tables = self.predictor.tables
        self._version = self.predictor.universe.version
        self._first = np.asarray(tables.first, dtype=np.int64)
        self._second = np.asarray(tables.second, dtype=np.int64)
        self._kind = np.asarray(tables.kind, dtype=np.int64)
        self._pair_geom1 = np.asarray(tables.geom1, dtype=np.int64)
        self._pair_geom2 = np.asarray(tables.geom2, dtype=np.int64)

    # ------------------------------------------------------------------- urgency

    def standing_pairs(self) -> np.ndarray:
        """``(k,)`` ids of the active sphere pairs standing in alarm now (empty before
        ``predictor.reset``): the pairs whose geoms are tinted and whose connectors are drawn."""
        if self.predictor.scheduler is None or self.predictor.nsphere_pairs == 0:
            return np.zeros(0, dtype=np.int64)
        if self._version != self.predictor.universe.version:
            self._read_tables()
        # By the model's pair ids: a pruned predictor's scheduler holds only some of them.
        state = self.predictor.pair_state()
        return np.flatnonzero(state.alarm_state() & state.active)

    def geom_urgency(self, standing: np.ndarray | None = None) -> np.ndarray:
        """tau, in predictor periods, of each geom's most urgent pair standing in alarm.

        Args:
            standing: :meth:`standing_pairs`, when the caller has them (None: read them).

        Returns:
            ``(ngeom,)`` float64: the minimum of ``last_tau / dt`` over the geom's active sphere
            pairs that stand in alarm (``-inf``, a pair switched back on, counts as 0); ``inf``
            for geoms with no alarmed pair, and for all geoms before ``predictor.reset``. Only
            those geoms are tinted: the rest of the scene is not urgent and keeps its colours.
        """
        out = np.full(self.predictor.model.ngeom, np.inf)
        pairs = self.standing_pairs() if standing is None else standing
        if pairs.size == 0:
            return out
        tau = self.predictor.pair_state().last_tau_of(pairs)
        steps = np.maximum(tau, 0.0) / self.predictor.dt
        np.minimum.at(out, self._pair_geom1[pairs], steps)
        geom2 = self._pair_geom2[pairs]
        valid = geom2 >= 0
        np.minimum.at(out, geom2[valid], steps[valid])
        return out

    def geom_levels(self, standing: np.ndarray | None = None) -> np.ndarray:
        """``(ngeom,)`` int level per geom: 0 imminent, 1 near, 2 alarmed, 3 not alarmed
        (``standing`` as for :meth:`geom_urgency`)."""
        urgency = self.geom_urgency(standing)
        levels = np.searchsorted(np.asarray(URGENCY_LEVELS), urgency, side="right")
        return np.where(np.isinf(urgency), len(URGENCY_LEVELS), levels)

    # ------------------------------------------------------------------- scene

    def add_to_scene(
        self, scene: mujoco.MjvScene, data: mujoco.MjData, alarms: Alarms | None
    ) -> int:
        """Tint the scene's model geoms and append connectors and spheres.

        Call it after ``mjv_updateScene`` (``Renderer.update_scene``) and before rendering. Geoms
        are appended at ``scene.ngeom`` until ``scene.maxgeom``; connectors go first, as they
        matter most when room is short.

        Args:
            scene: The scene to modify in place.
            data: The ``MjData`` the predictor read (sphere centres come from ``geom_xpos``).
            alarms: The latest step's alarms; None before ``reset`` (no connectors). The
                connectors are those of every pair standing in alarm (:meth:`standing_pairs`).

        Returns:
            The number of overlay geoms dropped because the scene was full (also added to
            :attr:`dropped`; the first drop warns with :class:`SceneFullWarning`).
        """
        opts = self.options
        # Read once: the tint, the connectors and the caller's count (``standing``) agree.
        self.standing = pairs = self.standing_pairs()
        levels = self.geom_levels(pairs)
        if opts.tint_geoms:
            self._tint(scene, levels)
        dropped = 0
        if opts.connectors and alarms is not None and pairs.size:
            # Every pair standing in alarm, not only those this step evaluated: with the
            # deadline schedule's backoff a resting contact is evaluated every few steps, and
            # its line would blink while its geoms stay tinted.
            start, end = self._connector_ends(data, pairs)
            dropped += self._add_connectors(scene, start, end)
        if opts.show_spheres and self.predictor.nsphere:
            dropped += self._add_spheres(scene, data, levels)
        if dropped:
            self.dropped += dropped
            if not self._warned:
                self._warned = True
                warnings.warn(
                    f"the MjvScene is full (maxgeom = {scene.maxgeom}): {dropped} overlay geom(s) "
                    "were not drawn. Pass a larger max_geom to OverlayRenderer (or "
                    "mujoco.MjvScene(model, maxgeom=...)), or hide the covering spheres.",
                    SceneFullWarning,
                    stacklevel=2,
                )
        return dropped

    def add_to_user_scn(self, viewer: Any, data: mujoco.MjData, alarms: Alarms | None) -> int:
        """Replace the overlay in a passive viewer's ``user_scn`` (call before ``viewer.sync()``).

        The user scene holds only the overlay, so tinting does nothing there: the model's geoms
        are tinted through ``geom_rgba`` (:meth:`tint_rgba`).

        Args:
            viewer: The handle of ``mujoco.viewer.launch_passive``.
            data: The ``MjData`` the predictor read.
            alarms: The alarms to draw.

        Returns:
            The number of overlay geoms dropped (see :meth:`add_to_scene`).
        """
        scn = getattr(viewer, "user_scn", None)
        if scn is None:
            raise InvalidInputError(
                f"{type(viewer).__name__} has no user_scn: pass the handle returned by "
                "mujoco.viewer.launch_passive(model, data)."
            )
        scn.ngeom = 0
        return self.add_to_scene(scn, data, alarms)

    def tint_rgba(self, rgba: np.ndarray, base: np.ndarray) -> None:
        """Write ``base`` into ``rgba`` with the tint of the latest :meth:`add_to_scene`.

        For the live viewer, which draws the model's own ``geom_rgba``: pass it as ``rgba`` and
        a copy of its original colours as ``base``. The same geoms get the same colours as in
        offscreen frames (only alpha is kept from ``base``). Does nothing to ``rgba`` beyond
        ``base`` when ``options.tint_geoms`` is off.

        Args:
            rgba: ``(ngeom, 4)`` float32, written in place (e.g. ``model.geom_rgba``).
            base: ``(ngeom, 4)`` the colours of geoms not tinted.
        """
        rgba[:] = base
        if not self.options.tint_geoms:
            return
        levels = self.geom_levels(self.standing)
        tint = self._tinted(levels)
        rgba[tint, :3] = TINTS[levels[tint]]

    def _tinted(self, levels: np.ndarray) -> np.ndarray:
        """``(ngeom,)`` bool: the geoms to tint (an alarmed level, and not welded to the world)."""
        return (levels < len(URGENCY_LEVELS)) & self._tintable

    def _tint(self, scene: mujoco.MjvScene, levels: np.ndarray) -> None:
        tint = self._tinted(levels)
        if not tint.any():
            return
        geoms = scene.geoms
        # The bindings expose scene geoms as structs, not arrays: one pass over the scene's
        # geoms (about ngeom, microseconds) is the only way to find a model geom's scene slot.
        for i in range(scene.ngeom):
            g = geoms[i]
            if g.objtype == _OBJ_GEOM and tint[g.objid]:
                g.rgba[:3] = TINTS[levels[g.objid]]

    def _connector_ends(
        self, data: mujoco.MjData, pairs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        cov = self.predictor.covering
        kind = self._kind[pairs]
        second = self._second[pairs]
        spheres = kind == int(PairKind.SPHERE)
        start = sphere_world_centers(cov, data.geom_xpos, data.geom_xmat, self._first[pairs])
        end = sphere_world_centers(
            cov, data.geom_xpos, data.geom_xmat, np.where(spheres, second, 0)
        )
        half = kind == int(PairKind.HALFSPACE)
        if half.any():
            normals, offsets = self.predictor.halfspaces(data)
            n = normals[second[half]]
            height = np.einsum("ij,ij->i", n, start[half]) - offsets[second[half]]
            end[half] = start[half] - height[:, None] * n
        shape = kind == int(PairKind.SHAPE)
        if shape.any():
            # To the nearest point of the static shape: the line shows what the sphere nears.
            records = self.predictor.shape_records
            for j in np.flatnonzero(shape).tolist():
                end[j] = closest_point(start[j], records[second[j]])
        return start, end

    def _add_connectors(self, scene: mujoco.MjvScene, start: np.ndarray, end: np.ndarray) -> int:
        rgba = np.asarray(ALARM_RGBA, dtype=np.float32)
        width = float(self.options.connector_width)
        for j in range(start.shape[0]):
            g = self._new_geom(scene, GEOM_LINE, _ZERO3, _ZERO3, rgba)
            if g is None:
                return start.shape[0] - j
            mujoco.mjv_connector(g, GEOM_LINE, width, start[j], end[j])
        return 0

    def _add_spheres(self, scene: mujoco.MjvScene, data: mujoco.MjData, levels: np.ndarray) -> int:
        cov = self.predictor.covering
        centres = sphere_world_centers(cov, data.geom_xpos, data.geom_xmat)
        nsphere = centres.shape[0]
        room = max(scene.maxgeom - scene.ngeom, 0)
        lvl = levels[np.asarray(cov.sphere_geom)]
        rgba = np.empty((nsphere, 4), dtype=np.float32)
        rgba[:, :3] = np.where(
            (lvl < len(URGENCY_LEVELS))[:, None],
            TINTS[np.minimum(lvl, len(URGENCY_LEVELS) - 1)],
            SPHERE_RGB,
        )
        rgba[:, 3] = self.options.sphere_alpha
        size = np.zeros((nsphere, 3))
        size[:, 0] = cov.sphere_radius
        # One mjv_initGeom per drawn sphere is inherent to the MjvScene API.
        for i in range(min(nsphere, room)):
            self._new_geom(scene, GEOM_SPHERE, size[i], centres[i], rgba[i])
        return nsphere - min(nsphere, room)

    @staticmethod
    def _new_geom(
        scene: mujoco.MjvScene, kind: int, size: np.ndarray, pos: np.ndarray, rgba: np.ndarray
    ) -> mujoco.MjvGeom | None:
        if scene.ngeom >= scene.maxgeom:
            return None
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, kind, size, pos, _EYE, rgba)
        # mjv_initGeom leaves these fields as they were; stale values would make an overlay geom
        # pass for a model geom (tinting, segmentation) or cast shadows.
        g.objtype = _OBJ_UNKNOWN
        g.objid = -1
        g.category = _CAT_DECOR
        g.segid = -1
        g.castshadow = False
        scene.ngeom += 1
        return g


# ----------------------------------------------------------------------------- offscreen
