"""Robot descriptions as URDF: TUDOR's rigid chain read from (and written to) a URDF file.

A URDF describes only the rigid chain: where the joints sit, their axes and their
limits. :func:`load_urdf_params` reads a URDF with ``yourdfpy`` and puts that chain into
a :class:`~tudorvision.robot.params.RobotParams`; everything a URDF cannot say (the elastic
blades' cross-section and material, gauges, friction, motors, payload masses, the
tracking spheres) comes from the packaged ``tudor.yaml`` or from a robot YAML given in
addition. :func:`load_robot` picks the reader from the file.

The chain must have TUDOR's structure (section 2.1), at zero joint angles:

* ``joint 1``: revolute (or continuous) about the base ``+z`` axis through the base origin;
* ``joint 2``: revolute about ``-y`` (positive angles lift the arm), on the ``z`` axis at
  height ``link1_height_m``;
* ``joint 3``: revolute about ``-y``, ``link2_length_m`` along ``+x`` from joint 2 at the
  same height;
* the end-effector frame (the tip link below joint 3: the only leaf link, or one named
  ``ee``, ``ee_link``, ``tool0`` or ``end_effector``) ``link3_length_m`` further along ``+x``.

Other chains are refused with a one-line error naming the joint (or link) that does not fit.
"""
from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from .params import RobotParams, load_robot_params

__all__ = ["load_urdf_params", "urdf_from_params", "load_robot", "is_urdf"]

_TOL = 1e-6
_TIP_NAMES = ("ee", "ee_link", "tool0", "end_effector")


def is_urdf(path: str | Path) -> bool:
    """Whether ``path`` names a URDF file (suffix ``.urdf``, or an XML file with a ``<robot`` element).

    Parameters
    ----------
    path : str or Path
        A robot description file.

    Returns
    -------
    bool
        True for a URDF, False for anything else (a robot YAML).
    """
    path = Path(path)
    if path.suffix.lower() in (".urdf", ".xml"):
        return True
    try:
        with open(path, "rb") as fh:
            head = fh.read(512).lstrip()
    except OSError:
        return False
    return head.startswith(b"<?xml") or head.startswith(b"<robot")


def load_robot(path: str | Path | None = None, *, elastic: str | Path | None = None) -> RobotParams:
    """Load a robot description: a robot YAML, or a URDF for the rigid chain.

    Parameters
    ----------
    path : str or Path, optional
        A robot YAML (see ``docs/own_hardware.md``) or a URDF (see :func:`load_urdf_params`);
        default the packaged ``tudor.yaml``.
    elastic : str or Path, optional
        With a URDF: the robot YAML that supplies everything but the rigid chain (default the
        packaged ``tudor.yaml``). With a YAML ``path`` it must be None.

    Returns
    -------
    RobotParams
        The parameters in SI units.

    Raises
    ------
    TudorVisionError
        For a missing or bad file; the one-line message names the file and the key, line or joint.
    """
    if path is not None and is_urdf(path):
        return load_urdf_params(path, base=load_robot_params(elastic) if elastic is not None else None)
    if elastic is not None:
        raise TudorVisionError(f"{elastic}: a second robot YAML only goes with a URDF (got {path})")
    return load_robot_params(path)


def _origin(joint) -> np.ndarray:
    return np.eye(4) if joint.origin is None else np.asarray(joint.origin, float)


def _read(path: Path):
    import yourdfpy
    if not path.is_file():
        raise TudorVisionError(f"{path}: URDF file not found")
    log = logging.getLogger("yourdfpy")          # it logs lxml's complaints; our one line says what is wrong
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        with np.errstate(all="ignore"):         # a NaN angle warns in trimesh; the chain check refuses it
            return yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                      build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as exc:  # yourdfpy/lxml raise many kinds for a broken file
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise TudorVisionError(f"{path}: not a readable URDF ({text[:160]})") from None
    finally:
        log.setLevel(level)


def _chain(path: Path, robot):
    """The three movable joints from the root (in order), their zero-angle poses and the tip link's pose."""
    joints = list(robot.robot.joints)
    children = {j.child for j in joints}
    roots = [lk.name for lk in robot.robot.links if lk.name not in children]
    if len(roots) != 1:
        raise TudorVisionError(f"{path}: expected one root link, found {len(roots)} ({', '.join(roots)})")
    below: dict[str, list] = {}
    for j in joints:
        below.setdefault(j.parent, []).append(j)
    for j in joints:
        if j.type not in ("revolute", "continuous", "fixed"):
            raise TudorVisionError(f"{path}: joint {j.name!r} is {j.type}; TUDOR's chain has revolute joints only")
    # depth-first from the root: pose of every link's frame at zero angles, and the movable joints on the way
    pose = {roots[0]: np.eye(4)}
    movable_path = {roots[0]: []}
    stack = [roots[0]]
    while stack:
        link = stack.pop()
        for j in below.get(link, []):
            if not np.all(np.isfinite(_origin(j))):
                raise TudorVisionError(f"{path}: joint {j.name!r}: its <origin> is not finite")
            if j.child in pose:
                raise TudorVisionError(f"{path}: link {j.child!r} is reached twice (joint {j.name!r}): the links "
                                       "must form a tree without loops, one parent joint per link")
            pose[j.child] = pose[link] @ _origin(j)
            movable_path[j.child] = movable_path[link] + ([j] if j.type != "fixed" else [])
            stack.append(j.child)
    apart = [j for j in joints if j.child not in pose]
    if apart:
        raise TudorVisionError(f"{path}: joint {apart[0].name!r} (parent link {apart[0].parent!r}) is not connected "
                               f"to the root link {roots[0]!r}")
    movable = [j for j in joints if j.type != "fixed"]
    if len(movable) != 3:
        names = ", ".join(j.name for j in movable) or "none"
        raise TudorVisionError(f"{path}: expected 3 revolute joints (base, shoulder, elbow), found "
                               f"{len(movable)} ({names})")
    order = max((movable_path[j.child] for j in movable), key=len)
    if len(order) != 3:
        stray = next(j for j in movable if j not in order)
        raise TudorVisionError(f"{path}: joint {stray.name!r} is not on one serial chain with the others")
    tip_parent = order[2].child
    leaves = [lk for lk in pose if not below.get(lk) and order[2] in movable_path[lk]]
    if leaves == [tip_parent]:
        raise TudorVisionError(f"{path}: joint {order[2].name!r}: its child link {tip_parent!r} has no "
                               "end-effector frame; add a fixed joint to a tip link (e.g. 'ee') at the link end")
    named = [lk for lk in leaves if lk in _TIP_NAMES]
    if len(leaves) == 1 or len(named) == 1:
        tip = leaves[0] if len(leaves) == 1 else named[0]
    else:
        raise TudorVisionError(f"{path}: several tip links below joint {order[2].name!r} ({', '.join(leaves)}); "
                               f"name the end-effector link one of {', '.join(_TIP_NAMES)}")
    frames = []
    for j in order:
        T = pose[j.parent] @ _origin(j)
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or not np.linalg.norm(axis) > 1e-9:
            raise TudorVisionError(f"{path}: joint {j.name!r}: axis {axis.tolist()} is not a direction")
        frames.append((T[:3, 3], T[:3, :3] @ (axis / np.linalg.norm(axis))))
    return order, frames, pose[tip][:3, 3], tip


def load_urdf_params(path: str | Path, *, base: RobotParams | None = None) -> RobotParams:
    """Read TUDOR's rigid chain (heights, link lengths, axes, limits) from a URDF.

    Parameters
    ----------
    path : str or Path
        URDF file with TUDOR's structure (see the module description).
    base : RobotParams, optional
        Supplies everything a URDF does not describe (elastic blades, friction, motors,
        payload, spheres); default the packaged ``tudor.yaml``. The blades' lengths follow
        the URDF's link lengths; joint ranges follow the URDF's ``<limit lower upper>``
        (continuous joints keep ``base``'s range), speeds its ``velocity`` and torque limits
        its ``effort`` where given (> 0).

    Returns
    -------
    RobotParams
        ``base`` with the URDF's rigid chain.

    Raises
    ------
    TudorVisionError
        If the file is missing or unreadable, or its chain does not fit TUDOR's structure;
        the one-line message names the file and the joint or link.
    """
    path = Path(path)
    base = base if base is not None else load_robot_params()
    order, frames, p_tip, tip = _chain(path, _read(path))
    (p1, a1), (p2, a2), (p3, a3) = frames
    j1, j2, j3 = (j.name for j in order)

    def fail(joint: str, text: str):
        raise TudorVisionError(f"{path}: joint {joint!r}: {text} (TUDOR's structure: docs/own_hardware.md)")

    if abs(a1[2] - 1.0) > _TOL:
        fail(j1, f"axis {np.round(a1, 6).tolist()} in the base frame; the base joint turns about +z [0, 0, 1]")
    if np.hypot(p1[0], p1[1]) > _TOL:
        fail(j1, "its axis does not pass through the base origin (x, y offset)")
    for name, a in ((j2, a2), (j3, a3)):
        if abs(a[1] + 1.0) > _TOL:
            fail(name, f"axis {np.round(a, 6).tolist()} at zero angles; the pitch joints turn about -y "
                       "[0, -1, 0] so that positive angles lift the arm, parallel to each other")
    if abs(p2[0]) > _TOL:
        fail(j2, f"its axis is {p2[0]:.6g} m off the base z axis along x; it must cross the base axis")
    l2, l3 = p3[0] - p2[0], p_tip[0] - p3[0]
    if abs(p3[2] - p2[2]) > _TOL or l2 <= _TOL:
        fail(j3, "at zero angles it must lie along +x from the shoulder joint at the same height "
                 "(the arm stretched out horizontally)")
    if abs(p_tip[2] - p3[2]) > _TOL or abs(p_tip[1]) > _TOL or l3 <= _TOL:
        raise TudorVisionError(f"{path}: link {tip!r}: the end-effector frame must lie along +x from joint "
                               f"{j3!r} at the same height, in the arm plane y = 0, at zero angles")
    return _with_chain(path, base, order, float(p2[2]), float(l2), float(l3))


def _with_chain(path: Path, base: RobotParams, order, h1: float, l2: float, l3: float) -> RobotParams:
    lim = np.array(base.joint_limits_rad, float)
    speed = np.array(base.max_speed_rad_s, float)
    torque = np.array(base.max_intermittent_torque_Nm, float)
    for i, j in enumerate(order):
        lm = j.limit
        if j.type == "revolute":
            if (lm is None or lm.lower is None or lm.upper is None or not lm.lower < lm.upper
                    or not np.isfinite([lm.lower, lm.upper]).all()):
                raise TudorVisionError(f"{path}: joint {j.name!r}: a revolute joint needs <limit lower upper> "
                                       "with finite lower < upper (radians)")
        for what in ("velocity", "effort"):
            v = getattr(lm, what, None) if lm is not None else None
            if v is not None and not np.isfinite(v):
                raise TudorVisionError(f"{path}: joint {j.name!r}: <limit {what}> is {v}, not a finite number")
            lim[i] = (lm.lower, lm.upper)
        if lm is not None and lm.velocity is not None and lm.velocity > 0:
            speed[i] = lm.velocity
        if lm is not None and lm.effort is not None and lm.effort > 0:
            torque[i] = lm.effort
    links = {}
    for name, length in (("link2", l2), ("link3", l3)):
        blade = dataclasses.replace(getattr(base, name), length_m=length)
        gauges = np.asarray(base.gauge_positions_m.get(name, []), float)
        if gauges.size and gauges.max() > length:
            raise TudorVisionError(f"{path}: {name} is {length:.4g} m long, shorter than its strain gauge at "
                                   f"{gauges.max():.4g} m (links.gauge_positions_m in the robot YAML)")
        links[name] = blade
    return base.replace(link1_height_m=h1, link2_length_m=l2, link3_length_m=l3, joint_limits_rad=_frozen(lim),
                        max_speed_rad_s=_frozen(speed), max_intermittent_torque_Nm=_frozen(torque), **links)


def _frozen(a) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def urdf_from_params(params: RobotParams | None = None, *, name: str = "tudor") -> str:
    """TUDOR's rigid chain as URDF text (what ``tudorvision robot export-urdf`` writes).

    Parameters
    ----------
    params : RobotParams, optional
        Default the packaged ``tudor.yaml``.
    name : str
        The ``<robot name>``.

    Returns
    -------
    str
        A URDF: links ``base_link``, ``link1``, ``link2``, ``link3`` and ``ee`` (the
        end-effector frame of :func:`tudorvision.robot.T_base_ee`), revolute joints ``joint1``
        to ``joint3`` with the ranges (rad), speeds (rad/s) and torque limits (N m), and
        the fixed joint ``ee_joint``. :func:`load_urdf_params` reads it back exactly.
    """
    p = params if params is not None else load_robot_params()
    lim, v, tau = p.joint_limits_rad, p.max_speed_rad_s, p.max_intermittent_torque_Nm
    joints = (("joint1", "base_link", "link1", (0.0, 0.0, 0.0), "0 0 1"),
              ("joint2", "link1", "link2", (0.0, 0.0, p.link1_height_m), "0 -1 0"),
              ("joint3", "link2", "link3", (p.link2_length_m, 0.0, 0.0), "0 -1 0"))
    out = ['<?xml version="1.0"?>',
           f'<!-- Rigid chain of {name} written by tudorvision (robot export-urdf); elastic blades, friction,',
           '     motors and payload live in the robot YAML (docs/own_hardware.md). -->',
           f'<robot name="{name}">']
    out += [f'  <link name="{lk}"/>' for lk in ("base_link", "link1", "link2", "link3", "ee")]
    for i, (jn, parent, child, xyz, axis) in enumerate(joints):
        out += [f'  <joint name="{jn}" type="revolute">',
                f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
                f'    <origin xyz="{" ".join(repr(float(x)) for x in xyz)}" rpy="0 0 0"/>',
                f'    <axis xyz="{axis}"/>',
                f'    <limit lower="{float(lim[i, 0])!r}" upper="{float(lim[i, 1])!r}" '
                f'velocity="{float(v[i])!r}" effort="{float(tau[i])!r}"/>',
                '  </joint>']
    out += ['  <joint name="ee_joint" type="fixed">', '    <parent link="link3"/>', '    <child link="ee"/>',
            f'    <origin xyz="{float(p.link3_length_m)!r} 0 0" rpy="{math.pi / 2!r} 0 0"/>',
            '  </joint>', '</robot>', '']
    return "\n".join(out)
