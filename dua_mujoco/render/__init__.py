"""Alarm overlays on MuJoCo scenes, headless frames and videos.

Modules: ``overlay`` (what is drawn), ``frames`` (headless frames), ``video`` (streamed videos),
``rollout`` (a monitored rollout into a video).
"""

from dua_mujoco.render.frames import MAX_FRAME_SIZE, OverlayRenderer, check_frame_size, status_line
from dua_mujoco.render.overlay import (
    ALARM_RGBA,
    SPHERE_RGB,
    TINTS,
    URGENCY_LEVELS,
    AlarmOverlay,
    OverlayOptions,
    SceneFullWarning,
)
from dua_mujoco.render.rollout import render_rollout
from dua_mujoco.render.video import (
    VIDEO_SUFFIXES,
    VideoWriter,
    check_mp4_size,
    read_video,
    use_bundled_ffmpeg,
    video_path,
    write_video,
)

__all__ = [
    "ALARM_RGBA",
    "MAX_FRAME_SIZE",
    "SPHERE_RGB",
    "TINTS",
    "URGENCY_LEVELS",
    "VIDEO_SUFFIXES",
    "AlarmOverlay",
    "OverlayOptions",
    "OverlayRenderer",
    "SceneFullWarning",
    "VideoWriter",
    "check_frame_size",
    "check_mp4_size",
    "read_video",
    "render_rollout",
    "status_line",
    "use_bundled_ffmpeg",
    "video_path",
    "write_video",
]
