"""``dua-mujoco export``: a scene with the predictor attached, for programs without Python.

Writes the scene's model with the sensor plugin ``dua_mujoco.predictor`` and its tables
(:func:`dua_mujoco.attach`), as MJCF (``.xml``) or MuJoCo's binary model (``.mjb``). A C or C++
program, or MuJoCo's ``simulate``, that loads ``libdua_mujoco.so`` runs the predictor in every
``mj_step`` of it (docs/plugin.md).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco

from dua_mujoco.exceptions import InvalidInputError

if TYPE_CHECKING:
    from dua_mujoco.runtime.predictor import Predictor

__all__ = ["DESCRIPTION", "EPILOG", "add_arguments", "export", "main"]

DESCRIPTION = (
    "Attach the predictor to a scene as the MuJoCo sensor plugin dua_mujoco.predictor (the run "
    "options choose its options, the pilot included) and write the model as MJCF (.xml) or "
    "MuJoCo's binary format (.mjb). Any program that loads libdua_mujoco.so (printed) runs the "
    "predictor in every mj_step; its sensor gives the pairs in alarm, the least tau, the "
    "evaluations, the deferred pairs and the bodies whose bounds broke."
)
EPILOG = "exit codes: 0 written; 2 bad input or an output that cannot be written."

_FORMATS = (".xml", ".mjb")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The scene, the output and the plugin's own options (the run options follow)."""
    p.add_argument("scene", help="bundled scene or MJCF path, as for run")
    p.add_argument("output", type=Path, help="where to write the model (.xml or .mjb)")
    p.add_argument(
        "--prefix", default="dua", help="name of the plugin instance and its sensor (default dua)"
    )
    p.add_argument("--no-overlay", action="store_true", help="draw nothing into the scene")


def export(
    spec: mujoco.MjSpec,
    output: Path,
    options: Callable[[mujoco.MjModel], dict[str, Any]],
    **attach_options: Any,
) -> Predictor:
    """Attach the predictor to ``spec`` and write the model as ``.xml`` or ``.mjb``.

    MuJoCo writes MJCF numbers with six significant digits: the geometry read back from the
    file is not the one compiled here, and tables computed for the latter could be a fraction
    of a micrometre short of the former. So for ``.xml`` the spec is written and read back
    first, and the predictor is built for the geometry the file will hold (its own tables
    survive exactly: base64 of their bytes). A ``.mjb`` holds the compiled model exactly. Relative
    asset folders are made absolute, so that the MJCF finds its meshes from wherever it is
    written.

    Args:
        spec: The scene's spec (edited).
        output: Where to write (``.xml`` or ``.mjb``).
        options: ``Predictor``'s keyword options for the model that will be written.
        **attach_options: :func:`~dua_mujoco.attach`'s own (``prefix``, ``overlay``).

    Returns:
        The Python twin of the predictor written (``attach``'s).

    Raises:
        InvalidInputError: The output's suffix is neither ``.xml`` nor ``.mjb``.
    """
    from dua_mujoco.plugin import attach

    suffix = output.suffix.lower()
    if suffix not in _FORMATS:
        raise InvalidInputError(
            f"output {str(output)!r} has suffix {suffix!r}: pass a path ending in "
            f"{' or '.join(_FORMATS)}."
        )
    if suffix == ".xml":
        if spec.modelfiledir:  # read from a file: its assets are found from its folder
            base = Path(spec.modelfiledir)
            for name in ("meshdir", "texturedir"):
                folder = getattr(spec, name)
                if not os.path.isabs(folder):
                    setattr(spec, name, str((base / folder).resolve()))
        spec.compile()  # to_xml writes what the last compilation saw
        spec = mujoco.MjSpec.from_string(spec.to_xml())
    p = attach(spec, **attach_options, **options(spec.compile()))
    if suffix == ".mjb":
        mujoco.mj_saveModel(spec.compile(), str(output), None)
    else:
        spec.compile()
        output.write_text(spec.to_xml())
    return p


def main(args: argparse.Namespace) -> int:
    """Run ``dua-mujoco export``; the exit code."""
    from dua_mujoco.models.scenes import load_spec
    from dua_mujoco.native import library_path
    from dua_mujoco.run_options import predictor_options

    p = export(
        load_spec(args.scene),
        args.output,
        lambda model: predictor_options(model, args),
        prefix=args.prefix,
        overlay=not args.no_overlay,
    )
    print(
        f"wrote {args.output}: {p.nsphere_pairs} sphere pairs of {len(p.geom_pairs)} geom pairs, "
        f"sensor {args.prefix!r}; run it with the plugin library {library_path()}"
    )
    return 0
