"""``tudorvision calib convert`` and the loader behind every ``--calib`` option.

Every command that takes a calibration file reads it with
:func:`load_calibration_arg`: our YAML, ROS camera_info (one file, or
``left.yaml,right.yaml``), OpenCV ``intrinsics.yml``/``extrinsics.yml`` and
Kalibr ``camchain.yaml`` are all accepted, and one line on stderr says which
format was read (see :mod:`tudorvision.io.calib_formats`).
"""
from __future__ import annotations

import sys
from pathlib import Path

from .._checks import TudorVisionError

__all__ = ["register", "load_calibration_arg"]


def load_calibration_arg(spec, *, option: str = "--calib", size=None, m_per_unit: float = 1.0):
    """Read the calibration a command-line option names, in any format; say on stderr what was read.

    Parameters
    ----------
    spec : str or Path
        The option's value: a file, ``a.yaml,b.yaml`` or a folder.
    option : str
        Option name, used in the error when the value is empty.
    size : tuple of int, optional
        ``(width, height)`` for OpenCV files without an image size (e.g. the
        sequence's image size).
    m_per_unit : float
        Metres per unit of an OpenCV extrinsics ``T``.

    Returns
    -------
    Calibration
        The calibration.

    Raises
    ------
    TudorVisionError
        Anything the loader refuses, as one line naming the file.
    """
    from ..io.calib_formats import load_any_calibration

    if not str(spec).strip():
        raise TudorVisionError(f"{option}: empty value")
    loaded = load_any_calibration(spec, size=size, m_per_unit=m_per_unit)
    print(f"calibration: read {loaded.summary}", file=sys.stderr)
    return loaded.calibration


def _size(text):
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise TudorVisionError(f"--size: expected WIDTHxHEIGHT in pixels, e.g. 640x480, got {text!r}") from None
    if w <= 0 or h <= 0:
        raise TudorVisionError(f"--size: expected positive pixels, got {text!r}")
    return w, h


def register(calib_sub) -> None:
    """Add ``convert`` to the ``calib`` group.

    Parameters
    ----------
    calib_sub : argparse subparsers
        The ``calib`` group's subcommands.
    """
    p = calib_sub.add_parser(
        "convert", help="convert a calibration between tudorvision, ROS, OpenCV and Kalibr files",
        description="Read a calibration in any supported format (tudorvision YAML, ROS camera_info: one file or "
                    "left.yaml,right.yaml or a folder with both; OpenCV intrinsics.yml,extrinsics.yml or a folder "
                    "with both; Kalibr camchain.yaml) and write it in another. What the target format has no "
                    "place for (transforms, rolling-shutter time, extra cameras) is listed and left out. See "
                    "docs/calibration_formats.md.")
    p.add_argument("input", metavar="IN", help="calibration file, 'a.yaml,b.yaml' pair, or folder")
    p.add_argument("--to", required=True, choices=("ros", "opencv", "kalibr", "tudorvision"), help="output format")
    p.add_argument("--out", required=True,
                   help="output: a file (tudorvision, kalibr, one ROS/OpenCV camera); for a stereo pair in ROS or "
                        "OpenCV a folder (left.yaml + right.yaml, intrinsics.yml + extrinsics.yml) or 'A,B'")
    p.add_argument("--size", metavar="WxH", help="image size for OpenCV input files that store none")
    p.add_argument("--m-per-unit", type=float, default=1.0, metavar="M",
                   help="OpenCV input and output: metres per unit of T (the square size if stereo_calib ran "
                        "without -s; default 1: metres)")
    p.add_argument("--allow-lossy", action="store_true",
                   help="Kalibr output: refit k1, k2 for a camera with k3 != 0 instead of refusing")
    p.set_defaults(func=run_convert)


def run_convert(args) -> int:
    """``tudorvision calib convert``: read IN in any format, write --out in --to."""
    from ..io.calib_formats import save_calibration_as

    if not args.m_per_unit > 0:
        raise TudorVisionError(f"--m-per-unit: must be positive, got {args.m_per_unit}")
    cal = load_calibration_arg(args.input, option="IN", size=_size(args.size), m_per_unit=args.m_per_unit)
    if not cal.cameras:
        raise TudorVisionError(f"{args.input}: the calibration has no camera to convert")
    out = Path(args.out)
    paths, notes = save_calibration_as(cal, args.to, out, allow_lossy=args.allow_lossy,
                                       m_per_unit=args.m_per_unit)
    for note in notes:
        print(f"note: {note}")
    for path in paths:
        print(f"wrote {path}")
    return 0
