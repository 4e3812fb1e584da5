"""Recorded sequences and calibration files.

Reading: :func:`open_sequence` (own directory format, TUM RGB-D, videos,
image folders), lazy :class:`Sequence` with :class:`StereoFrame`,
:class:`RGBDFrame`, :class:`MonoFrame`; :meth:`Sequence.play` for live-rate
playback. Writing: :class:`SequenceWriter`. Calibration: :class:`Calibration`
with :func:`load_calibration` / :func:`save_calibration`, ROS camera_info and
OpenCV stereo files in :mod:`tudorvision.io.formats`. Output files are written
atomically with :mod:`tudorvision.io.atomic`.

The names below are imported on first use (PEP 562): importing
``tudorvision.io.atomic`` or reading :data:`DEFAULT_MAX_PIXELS` does not load
OpenCV; ``from tudorvision.io import X`` works as usual.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:  # the same names, for type checkers and the import-layer checks
    from ._imageheader import DEFAULT_MAX_PIXELS
    from .atomic import atomic_path, atomic_write, write_bytes_atomic, write_text_atomic
    from .calibration import (Calibration, CameraModel, DepthModel, StereoExtrinsics, load_calibration,
                              save_calibration)
    from .formats import (CameraInfo, calibration_from_ros, load_opencv_stereo, load_ros_camera_info,
                          save_opencv_stereo, save_ros_camera_info)
    from .playback import Playback, Played
    from .frames import JointLog, MonoFrame, RGBDFrame, StereoFrame
    from .sequence import Sequence, load_joint_log, open_sequence
    from .writer import SequenceWriter

# submodule -> the names it provides here
_PROVIDERS = {
    "_imageheader": ("DEFAULT_MAX_PIXELS",),
    "atomic": ("atomic_path", "atomic_write", "write_bytes_atomic", "write_text_atomic"),
    "calibration": ("Calibration", "CameraModel", "DepthModel", "StereoExtrinsics", "load_calibration",
                    "save_calibration"),
    "formats": ("CameraInfo", "calibration_from_ros", "load_opencv_stereo", "load_ros_camera_info",
                "save_opencv_stereo", "save_ros_camera_info"),
    "playback": ("Playback", "Played"),
    "frames": ("JointLog", "MonoFrame", "RGBDFrame", "StereoFrame"),
    "sequence": ("Sequence", "load_joint_log", "open_sequence"),
    "writer": ("SequenceWriter",),
}

__all__ = [
    "open_sequence", "Sequence", "load_joint_log", "StereoFrame", "RGBDFrame", "MonoFrame", "JointLog",
    "Playback", "Played", "SequenceWriter",
    "Calibration", "CameraModel", "StereoExtrinsics", "DepthModel", "load_calibration",
    "save_calibration", "CameraInfo", "load_ros_camera_info", "save_ros_camera_info",
    "calibration_from_ros", "load_opencv_stereo", "save_opencv_stereo",
    "DEFAULT_MAX_PIXELS", "atomic_write", "atomic_path", "write_text_atomic", "write_bytes_atomic",
]


__getattr__, __dir__ = lazy_exports(__name__, _PROVIDERS, globals(), __all__)
