"""TUDOR robot parameters loaded from the single data file ``data/tudor.yaml``."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from .._checks import TudorVisionError

__all__ = ["RobotParams", "LinkParams", "load_robot_params", "DEFAULT_PARAMS_PATH"]

DEFAULT_PARAMS_PATH = Path(str(resources.files("tudorvision.robot").joinpath("data/tudor.yaml")))


@dataclass(frozen=True, kw_only=True)
class LinkParams:
    """An elastic spring-steel blade (appendix A.1). SI units.

    Parameters
    ----------
    length_m : float
        Blade length in metres.
    width_m : float
        Blade width in metres (horizontal, across the bending plane).
    height_m : float
        Blade thickness in metres (in the arm's vertical bending plane).
    density_kg_m3 : float
        Material density in kg/m^3.
    youngs_modulus_Pa : float
        Young's modulus in pascals.
    """

    length_m: float
    width_m: float
    height_m: float
    density_kg_m3: float
    youngs_modulus_Pa: float

    @property
    def area_m2(self) -> float:
        return self.width_m * self.height_m

    @property
    def mass_per_length_kg_m(self) -> float:
        """Beam density per unit length, the seed's rho_b."""
        return self.density_kg_m3 * self.area_m2

    @property
    def mass_kg(self) -> float:
        return self.mass_per_length_kg_m * self.length_m

    @property
    def second_moment_m4(self) -> float:
        """Area moment of inertia for bending in the arm's vertical plane (b h^3 / 12)."""
        return self.width_m * self.height_m**3 / 12.0

    @property
    def flexural_rigidity_Nm2(self) -> float:
        return self.youngs_modulus_Pa * self.second_moment_m4


@dataclass(frozen=True, kw_only=True)
class RobotParams:
    """All TUDOR parameters. Angles in radians, lengths in metres.

    Build with :func:`load_robot_params`; override single values with
    ``dataclasses.replace(params, link1_height_m=0.4)``.

    Parameters
    ----------
    gravity_m_s2 : float
        Gravitational acceleration in m/s^2.
    link1_height_m : float
        Height of the shoulder (joint 2 axis) above the base origin, metres.
    link2_length_m, link3_length_m : float
        Rigid-equivalent lengths of links 2 and 3, metres.
    sphere_radius_m : float
        Radius of the red and green tracking spheres, metres.
    sphere_offsets_ee_m : dict
        ``{"red": (3,), "green": (3,)}`` sphere centres in the end-effector frame, metres.
    joint_limits_rad : ndarray, shape (3, 2)
        ``[lower, upper]`` range of each joint, radians.
    max_speed_rad_s, max_accel_rad_s2 : ndarray, shape (3,)
        Joint speed (rad/s) and acceleration (rad/s^2) limits.
    experiment_speed_rad_s, experiment_accel_rad_s2 : float
        Speed and acceleration used by the seed's experiments.
    gear_ratio, rotor_inertia_kg_m2 : ndarray, shape (3,)
        Gear ratio and rotor inertia (kg m^2, motor side) per joint.
    viscous_pos_Nms_rad, viscous_neg_Nms_rad : ndarray, shape (3,)
        Viscous friction for positive and negative velocity, N m s/rad.
    coulomb_pos_Nm, coulomb_neg_Nm : ndarray, shape (3,)
        Coulomb friction for positive and negative velocity, N m.
    torque_constant_Nm_A, amplifier_gain_A_V, amplifier_cutoff_hz : ndarray, shape (3,)
        Motor torque constant (N m/A), amplifier gain (A/V) and cut-off (Hz) per joint.
    max_intermittent_torque_Nm : ndarray, shape (3,)
        Intermittent torque limit per joint, N m.
    actuator_mass_kg : ndarray
        Masses of the actuators carried by the links, kg.
    link2, link3 : LinkParams
        The elastic blades of links 2 and 3.
    gauge_positions_m : dict
        Strain-gauge positions along each link from its root, metres.
    modal_damping_ratio : ndarray
        Damping ratio of each retained bending mode (dimensionless).
    plate_mass_kg, camera_and_spheres_mass_kg, end_effector_mount_mass_kg, ball_mass_kg : float
        Masses of one payload plate, the camera with spheres, the end-effector mount and the ball, kg.
    extra : dict, optional
        Further keys of the parameter file, unparsed.
    """

    gravity_m_s2: float
    link1_height_m: float
    link2_length_m: float
    link3_length_m: float
    sphere_radius_m: float
    sphere_offsets_ee_m: dict
    joint_limits_rad: np.ndarray            # (3, 2)
    max_speed_rad_s: np.ndarray             # (3,)
    max_accel_rad_s2: np.ndarray            # (3,)
    experiment_speed_rad_s: float
    experiment_accel_rad_s2: float
    gear_ratio: np.ndarray
    rotor_inertia_kg_m2: np.ndarray
    viscous_pos_Nms_rad: np.ndarray
    viscous_neg_Nms_rad: np.ndarray
    coulomb_pos_Nm: np.ndarray
    coulomb_neg_Nm: np.ndarray
    torque_constant_Nm_A: np.ndarray
    amplifier_gain_A_V: np.ndarray
    amplifier_cutoff_hz: np.ndarray
    max_intermittent_torque_Nm: np.ndarray
    actuator_mass_kg: np.ndarray
    link2: LinkParams
    link3: LinkParams
    gauge_positions_m: dict
    modal_damping_ratio: np.ndarray
    plate_mass_kg: float
    camera_and_spheres_mass_kg: float
    end_effector_mount_mass_kg: float
    ball_mass_kg: float
    extra: dict = field(default_factory=dict)

    def replace(self, **changes) -> "RobotParams":
        """Return a copy with some fields changed.

        Parameters
        ----------
        **changes
            Field names and their new values.

        Returns
        -------
        RobotParams
            A new parameter set; ``self`` is unchanged.
        """
        return dataclasses.replace(self, **changes)


def _arr(x) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    a.setflags(write=False)
    return a


_BLADE_KEYS = ("length_m", "width_m", "height_m", "density_kg_m3", "youngs_modulus_Pa")

# key path -> (kind, shape). kinds: "pos" > 0, "nonneg" >= 0, "any" finite. shape: None scalar,
# an int n: a list of n numbers, "n": a list of any length >= 1, "range": 3 [lower, upper] pairs,
# "vec3map": a mapping of names to 3 numbers, "listmap": a mapping of names to lists of numbers.
_SCHEMA = {
    "gravity_m_s2": ("pos", None),
    "kinematics.link1_height_m": ("nonneg", None),
    "kinematics.link2_length_m": ("pos", None),
    "kinematics.link3_length_m": ("pos", None),
    "kinematics.sphere_radius_m": ("pos", None),
    "kinematics.sphere_offsets_ee_m": ("any", "vec3map"),
    "joints.range_deg": ("any", "range"),
    "joints.max_speed_deg_s": ("pos", 3),
    "joints.max_accel_deg_s2": ("pos", 3),
    "joints.experiment_speed_deg_s": ("pos", None),
    "joints.experiment_accel_deg_s2": ("pos", None),
    "joints.gear_ratio": ("pos", 3),
    "joints.rotor_inertia_kg_m2": ("pos", 3),
    "joints.viscous_pos_Nms_rad": ("nonneg", 3),
    "joints.viscous_neg_Nms_rad": ("nonneg", 3),
    "joints.coulomb_pos_Nm": ("nonneg", 3),
    "joints.coulomb_neg_Nm": ("nonneg", 3),
    "joints.torque_constant_Nm_A": ("pos", 3),
    "joints.amplifier_gain_A_V": ("pos", 3),
    "joints.amplifier_cutoff_hz": ("pos", 3),
    "joints.max_intermittent_torque_Nm": ("pos", 3),
    "joints.actuator_mass_kg": ("nonneg", 3),
    **{f"links.{link}.{key}": ("pos", None) for link in ("link2", "link3") for key in _BLADE_KEYS},
    "links.gauge_positions_m": ("nonneg", "listmap"),
    "links.modal_damping_ratio": ("nonneg", "n"),
    "payload.plate_mass_kg": ("nonneg", None),
    "payload.camera_and_spheres_mass_kg": ("nonneg", None),
    "payload.end_effector_mount_mass_kg": ("nonneg", None),
    "payload.ball_mass_kg": ("nonneg", None),
}
_SCHEMA_TOP = {"name"} | {k.split(".")[0] for k in _SCHEMA}
_KIND_TEXT = {"pos": "a number > 0", "nonneg": "a number >= 0", "any": "a finite number"}


def _key_line(text: str, keys: list[str]) -> str:
    """`` line N`` of the deepest existing key on ``keys`` in the YAML ``text``, or ``""``."""
    try:
        node = yaml.compose(text)
    except yaml.YAMLError:
        return ""
    line = ""
    for key in keys:
        if not isinstance(node, yaml.MappingNode):
            break
        hit = next(((k, v) for k, v in node.value if getattr(k, "value", None) == key), None)
        if hit is None:
            break
        line, node = f" line {hit[0].start_mark.line + 1}", hit[1]
    return line


def _number(value, kind: str) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    v = float(value)
    return bool(np.isfinite(v)) and (kind != "pos" or v > 0) and (kind != "nonneg" or v >= 0)


def _numbers(value, kind: str, n=None) -> bool:
    return (isinstance(value, list) and len(value) >= 1 and (n is None or len(value) == n)
            and all(_number(v, kind) for v in value))


def _value_ok(value, kind: str, shape) -> str | None:
    """``None`` when ``value`` fits, else what was expected."""
    what = _KIND_TEXT[kind]
    if shape is None:
        return None if _number(value, kind) else what
    if isinstance(shape, int):
        return None if _numbers(value, kind, shape) else f"a list of {shape} numbers, each {what[2:]}"
    if shape == "n":
        return None if _numbers(value, kind) else f"a list of numbers, each {what[2:]}"
    if shape == "range":
        ok = (isinstance(value, list) and len(value) == 3
              and all(_numbers(r, "any", 2) and r[0] < r[1] for r in value))
        return None if ok else "3 [lower, upper] pairs of degrees with lower < upper"
    n = 3 if shape == "vec3map" else None
    ok = (isinstance(value, dict) and len(value) >= 1
          and all(isinstance(k, str) and _numbers(v, kind, n) for k, v in value.items()))
    return None if ok else ("a mapping of names to [x, y, z] metres" if n else
                            f"a mapping of link names to lists of numbers, each {what[2:]}")


def _validate(doc: dict, path: Path, text: str) -> None:
    """Raise a one-line :class:`TudorVisionError` naming the file, key and line of the first bad entry."""
    for dotted, (kind, shape) in _SCHEMA.items():
        keys = dotted.split(".")
        node = doc
        for i, key in enumerate(keys):
            if not isinstance(node, dict):
                where = ".".join(keys[:i])
                raise TudorVisionError(f"{path}:{_key_line(text, keys[:i])} {where}: expected a mapping of keys")
            if key not in node:
                parent = ".".join(keys[:i]) or "the top level"
                raise TudorVisionError(f"{path}:{_key_line(text, keys[:i])} missing key {dotted!r} "
                                       f"(in {parent}; see docs/own_hardware.md)")
            node = node[key]
        problem = _value_ok(node, kind, shape)
        if problem is not None:
            raise TudorVisionError(f"{path}:{_key_line(text, keys)} {dotted}: expected {problem}, got {node!r}")
    gauges = doc["links"]["gauge_positions_m"]
    for link in ("link2", "link3"):
        length = float(doc["links"][link]["length_m"])
        pos = gauges.get(link, [])
        if any(float(x) > length for x in pos):
            keys = ["links", "gauge_positions_m", link]
            raise TudorVisionError(f"{path}:{_key_line(text, keys)} links.gauge_positions_m.{link}: "
                                   f"a gauge lies beyond the blade length {length} m")


def load_robot_params(path: str | Path | None = None) -> RobotParams:
    """Load robot parameters from a YAML file (default: the packaged ``tudor.yaml``).

    Parameters
    ----------
    path : str or Path, optional
        YAML parameter file; default :data:`DEFAULT_PARAMS_PATH` (the packaged ``tudor.yaml``).

    Returns
    -------
    RobotParams
        The parsed parameters in SI units.

    Raises
    ------
    TudorVisionError
        If the file is missing, malformed, lacks a key, or a value has the wrong type or sign
        (a non-positive length, say); the one-line message names the file, the key and its line.

    Examples
    --------
    >>> p = load_robot_params()
    >>> round(p.link2_length_m, 3)
    0.43
    """
    path = Path(path) if path is not None else DEFAULT_PARAMS_PATH
    try:
        text = path.read_text()
        doc = yaml.safe_load(text)
    except (FileNotFoundError, IsADirectoryError):
        raise TudorVisionError(f"{path}: robot parameter file not found") from None
    except UnicodeDecodeError:
        raise TudorVisionError(f"{path}: not a text (YAML) file") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        raise TudorVisionError(f"{path}:{line} malformed YAML") from None
    if not isinstance(doc, dict):
        raise TudorVisionError(f"{path}: expected a YAML mapping of robot parameters (see docs/own_hardware.md)")
    _validate(doc, path, text)
    kin, jnt, lnk, pay = doc["kinematics"], doc["joints"], doc["links"], doc["payload"]
    deg = np.pi / 180.0
    return RobotParams(
        gravity_m_s2=float(doc["gravity_m_s2"]),
        link1_height_m=float(kin["link1_height_m"]),
        link2_length_m=float(kin["link2_length_m"]),
        link3_length_m=float(kin["link3_length_m"]),
        sphere_radius_m=float(kin["sphere_radius_m"]),
        sphere_offsets_ee_m={k: _arr(v) for k, v in kin["sphere_offsets_ee_m"].items()},
        joint_limits_rad=_arr(np.asarray(jnt["range_deg"], float) * deg),
        max_speed_rad_s=_arr(np.asarray(jnt["max_speed_deg_s"], float) * deg),
        max_accel_rad_s2=_arr(np.asarray(jnt["max_accel_deg_s2"], float) * deg),
        experiment_speed_rad_s=float(jnt["experiment_speed_deg_s"]) * deg,
        experiment_accel_rad_s2=float(jnt["experiment_accel_deg_s2"]) * deg,
        gear_ratio=_arr(jnt["gear_ratio"]),
        rotor_inertia_kg_m2=_arr(jnt["rotor_inertia_kg_m2"]),
        viscous_pos_Nms_rad=_arr(jnt["viscous_pos_Nms_rad"]),
        viscous_neg_Nms_rad=_arr(jnt["viscous_neg_Nms_rad"]),
        coulomb_pos_Nm=_arr(jnt["coulomb_pos_Nm"]),
        coulomb_neg_Nm=_arr(jnt["coulomb_neg_Nm"]),
        torque_constant_Nm_A=_arr(jnt["torque_constant_Nm_A"]),
        amplifier_gain_A_V=_arr(jnt["amplifier_gain_A_V"]),
        amplifier_cutoff_hz=_arr(jnt["amplifier_cutoff_hz"]),
        max_intermittent_torque_Nm=_arr(jnt["max_intermittent_torque_Nm"]),
        actuator_mass_kg=_arr(jnt["actuator_mass_kg"]),
        link2=LinkParams(**{k: float(lnk["link2"][k]) for k in _BLADE_KEYS}),
        link3=LinkParams(**{k: float(lnk["link3"][k]) for k in _BLADE_KEYS}),
        gauge_positions_m={k: _arr(v) for k, v in lnk["gauge_positions_m"].items()},
        modal_damping_ratio=_arr(lnk["modal_damping_ratio"]),
        plate_mass_kg=float(pay["plate_mass_kg"]),
        camera_and_spheres_mass_kg=float(pay["camera_and_spheres_mass_kg"]),
        end_effector_mount_mass_kg=float(pay["end_effector_mount_mass_kg"]),
        ball_mass_kg=float(pay["ball_mass_kg"]),
        extra={k: v for k, v in doc.items() if k not in _SCHEMA_TOP},
    )
