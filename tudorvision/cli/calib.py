"""The ``tudorvision calib`` command group.

Each module in ``CALIB_MODULES`` has ``register(calib_subparsers)``.
"""
from __future__ import annotations

import importlib

__all__ = ["register"]

CALIB_MODULES = (
    "tudorvision.cli.calib_stereo",
    "tudorvision.cli.calib_rgbd",
    "tudorvision.cli.calib_convert",
)


def register(sub) -> None:
    p = sub.add_parser("calib", help="camera and camera-to-robot calibration",
                       description="Camera and camera-to-robot calibration.")
    calib_sub = p.add_subparsers(dest="calib_command", metavar="KIND")
    for name in CALIB_MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        mod.register(calib_sub)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
