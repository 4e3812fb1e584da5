"""Robot description files (issue 16): the documented YAML, URDF for the rigid chain, ``--robot FILE``.

Oracles: ``tudorvision.robot`` forward kinematics of the packaged YAML, and yourdfpy's own
forward kinematics of the exported URDF (an independent implementation).
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.cli import build_parser, main
from tudorvision.robot import (DEFAULT_PARAMS_PATH, T_base_ee, fk_ee, load_robot, load_robot_params,
                               load_urdf_params, urdf_from_params)

YAML_TEXT = DEFAULT_PARAMS_PATH.read_text()


def _line_of(text: str, needle: str) -> int:
    return next(i + 1 for i, line in enumerate(text.splitlines()) if needle in line)


# ----------------------------------------------------------------------------------------- YAML errors

@pytest.mark.parametrize("old, new, key, line_needle", [
    ("link2_length_m: 0.430", "link2_length_m: -0.43", "kinematics.link2_length_m", "link2_length_m:"),
    ("link2_length_m: 0.430", "link2_length_m: 0", "kinematics.link2_length_m", "link2_length_m:"),
    ("link3_length_m: 0.410", "link3_length_m: long", "kinematics.link3_length_m", "link3_length_m:"),
    ("max_speed_deg_s: [184.0, 125.0, 146.0]", "max_speed_deg_s: [184.0, 125.0]", "joints.max_speed_deg_s",
     "max_speed_deg_s:"),
    ("gear_ratio: [156.0, 230.0, 246.0]", "gear_ratio: [156.0, -230.0, 246.0]", "joints.gear_ratio",
     "gear_ratio:"),
    ("range_deg: [[-170.0, 180.0]", "range_deg: [[180.0, -170.0]", "joints.range_deg", "range_deg:"),
    ("youngs_modulus_Pa: 2.0e+11}\n  link3", "youngs_modulus_Pa: -1}\n  link3", "links.link2.youngs_modulus_Pa",
     "link2: {length_m"),
    ("ball_mass_kg: 0.030", "ball_mass_kg: true", "payload.ball_mass_kg", "ball_mass_kg:"),
])
def test_yaml_bad_value_names_file_key_and_line(tmp_path, old, new, key, line_needle):
    assert YAML_TEXT.count(old) == 1
    text = YAML_TEXT.replace(old, new)
    f = tmp_path / "arm.yaml"
    f.write_text(text)
    with pytest.raises(TudorVisionError) as err:
        load_robot_params(f)
    msg = str(err.value)
    assert "\n" not in msg and str(f) in msg and key in msg
    assert f"line {_line_of(text, line_needle)}" in msg


def test_yaml_missing_key_and_malformed(tmp_path):
    f = tmp_path / "arm.yaml"
    f.write_text("\n".join(line for line in YAML_TEXT.splitlines() if "link3_length_m" not in line))
    with pytest.raises(TudorVisionError, match=r"arm\.yaml: line \d+ missing key 'kinematics\.link3_length_m'"):
        load_robot_params(f)
    f.write_text(YAML_TEXT.replace("kinematics:", "kinematics: [", 1))
    with pytest.raises(TudorVisionError, match=r"arm\.yaml: line \d+ malformed YAML"):
        load_robot_params(f)
    f.write_text("- just\n- a list\n")
    with pytest.raises(TudorVisionError, match="expected a YAML mapping"):
        load_robot_params(f)
    with pytest.raises(TudorVisionError, match="not found"):
        load_robot_params(tmp_path / "absent.yaml")


def test_yaml_changed_value_is_used(tmp_path):
    f = tmp_path / "arm.yaml"
    f.write_text(YAML_TEXT.replace("link1_height_m: 0.35", "link1_height_m: 0.5"))
    p = load_robot_params(f)
    assert p.link1_height_m == 0.5
    assert np.allclose(fk_ee([0.0, 0.0, 0.0], p), [0.84, 0.0, 0.5])


# ----------------------------------------------------------------------------------------- URDF

def _export(tmp_path, *extra) -> str:
    out = tmp_path / "tudor.urdf"
    assert main(["robot", "export-urdf", "--out", str(out), *extra]) == 0
    return str(out)


def test_urdf_round_trip_matches_yaml_kinematics(tmp_path):
    path = _export(tmp_path)
    p_urdf, p_yaml = load_robot(path), load_robot_params()
    rng = np.random.default_rng(16)
    lim = np.asarray(p_yaml.joint_limits_rad)
    th = rng.uniform(lim[:, 0], lim[:, 1], size=(200, 3))
    assert np.allclose(fk_ee(th, p_urdf), fk_ee(th, p_yaml), atol=1e-12)
    assert np.allclose(T_base_ee(th, p_urdf), T_base_ee(th, p_yaml), atol=1e-12)
    assert np.array_equal(p_urdf.joint_limits_rad, p_yaml.joint_limits_rad)
    assert np.allclose(p_urdf.max_speed_rad_s, p_yaml.max_speed_rad_s)
    assert p_urdf.link2 == p_yaml.link2 and p_urdf.gear_ratio.tolist() == p_yaml.gear_ratio.tolist()


def test_exported_urdf_agrees_with_yourdfpy_fk(tmp_path):
    import yourdfpy
    urdf = yourdfpy.URDF.load(_export(tmp_path), load_meshes=False)
    rng = np.random.default_rng(3)
    for th in rng.uniform(-2.5, 2.5, size=(20, 3)):
        urdf.update_cfg(th)
        assert np.allclose(urdf.get_transform("ee", "base_link"), T_base_ee(th), atol=1e-12)


def test_urdf_with_yaml_takes_chain_from_urdf_rest_from_yaml(tmp_path):
    path = _export(tmp_path)
    f = tmp_path / "mine.yaml"
    f.write_text(YAML_TEXT.replace("link1_height_m: 0.35", "link1_height_m: 0.9")
                 .replace("ball_mass_kg: 0.030", "ball_mass_kg: 0.25"))
    args = build_parser().parse_args(["robot", "check", "--robot", str(f), "--robot", path])
    from tudorvision.cli.robot_args import robot_from_args
    p = robot_from_args(args)
    assert p.link1_height_m == pytest.approx(0.35) and p.ball_mass_kg == 0.25


def _write(tmp_path, text, name="arm.urdf"):
    f = tmp_path / name
    f.write_text(text)
    return f


@pytest.mark.parametrize("old, new, pattern", [
    ('<joint name="joint2" type="revolute">', '<joint name="joint2" type="prismatic">',
     r"joint 'joint2' is prismatic"),
    ('<axis xyz="0 -1 0"/>', '<axis xyz="0 1 0"/>', r"joint 'joint2': axis \[0\.0, 1\.0, 0\.0\]"),
    ('<axis xyz="0 0 1"/>', '<axis xyz="1 0 0"/>', r"joint 'joint1': axis"),
    ('<origin xyz="0.0 0.0 0.35" rpy="0 0 0"/>', '<origin xyz="0.05 0.0 0.35" rpy="0 0 0"/>',
     r"joint 'joint2': its axis is 0\.05 m off"),
    ('<origin xyz="0.43 0.0 0.0" rpy="0 0 0"/>', '<origin xyz="0.0 0.0 0.43" rpy="0 0 0"/>',
     r"joint 'joint3': at zero angles it must lie along \+x"),
])
def test_urdf_that_does_not_fit_is_refused_naming_the_joint(tmp_path, old, new, pattern):
    text = urdf_from_params()
    assert old in text
    f = _write(tmp_path, text.replace(old, new, 1))
    with pytest.raises(TudorVisionError, match=pattern) as err:
        load_urdf_params(f)
    assert str(f) in str(err.value) and "\n" not in str(err.value)


def test_urdf_structure_errors(tmp_path):
    text = urdf_from_params()
    no_tip = re.sub(r'  <joint name="ee_joint".*?</joint>\n', "", text, flags=re.S).replace('  <link name="ee"/>\n', "")
    with pytest.raises(TudorVisionError, match="joint 'joint3': its child link 'link3' has no end-effector frame"):
        load_urdf_params(_write(tmp_path, no_tip))
    with pytest.raises(TudorVisionError, match="expected 3 revolute joints"):
        load_urdf_params(_write(tmp_path, '<robot name="x"><link name="a"/></robot>'))
    with pytest.raises(TudorVisionError, match="not a readable URDF"):
        load_urdf_params(_write(tmp_path, "<robot name='x'><link"))
    assert main(["robot", "check", "--robot", str(tmp_path / "nope.urdf")]) == 2


@pytest.mark.parametrize("old, new, pattern", [
    # found by fuzzing: a NaN origin used to load as NaN link lengths, silently
    ('<origin xyz="0.43 0.0 0.0" rpy="0 0 0"/>', '<origin xyz="nan 0.0 0.0" rpy="0 0 0"/>',
     r"joint 'joint3': its <origin> is not finite"),
    ('<origin xyz="0.0 0.0 0.35" rpy="0 0 0"/>', '<origin xyz="0.0 0.0 0.35" rpy="nan 0 0"/>',
     r"joint 'joint2': its <origin> is not finite"),
    ('upper="1.7802358370342162"', 'upper="inf"', r"joint 'joint3': .*finite lower < upper"),
    ('velocity="2.181661564992912"', 'velocity="inf"', r"joint 'joint2': <limit velocity> is inf"),
    ('effort="7.5"', 'effort="nan"', r"joint 'joint3': <limit effort> is nan"),
    ('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', r"joint 'joint1': axis \[0\.0, 0\.0, 0\.0\] is not a direction"),
    # found by fuzzing: a joint hanging from a link that is not on the tree was a KeyError
    ('<parent link="link2"/>', '<parent link="linkX"/>', r"joint 'joint3' \(parent link 'linkX'\) is not connected"),
    ('<child link="ee"/>', '<child link="link2"/>', r"link 'link2' is reached twice"),   # a loop
])
def test_urdf_with_non_finite_or_broken_tree_is_refused(tmp_path, old, new, pattern):
    text = urdf_from_params()
    assert old in text
    f = _write(tmp_path, text.replace(old, new, 1).replace('  <link name="ee"/>\n', "" if "ee" in old else "  <link name=\"ee\"/>\n"))
    with pytest.raises(TudorVisionError, match=pattern) as err:
        load_urdf_params(f)
    assert str(f) in str(err.value) and "\n" not in str(err.value)


# ----------------------------------------------------------------------------------------- sim ptp

def _ptp(tmp_path, name, *robot):
    out = tmp_path / f"{name}.csv"
    assert main(["sim", "ptp", "--from", "0,90,0", "--to", "0,80,10", "--duration", "0.3", "--plates", "0",
                 "--out", str(out), *robot]) == 0
    return np.loadtxt(out, delimiter=",")


def test_longer_link_in_urdf_moves_sim_ptp_end_effector(tmp_path):
    path = _export(tmp_path)
    longer = tmp_path / "longer.urdf"
    text = open(path).read()
    old = '<origin xyz="0.43 0.0 0.0" rpy="0 0 0"/>'
    assert text.count(old) == 1
    longer.write_text(text.replace(old, '<origin xyz="0.53 0.0 0.0" rpy="0 0 0"/>'))
    base, long_ = _ptp(tmp_path, "base"), _ptp(tmp_path, "long", "--robot", str(longer))
    ee_b, ee_l = base[:, 8:11], long_[:, 8:11]
    # upright at rest: gravity along both links, so the tip rises by exactly the extra 0.1 m; sideways the
    # soft plant's hub springs and backlash tilt both arms alike, the longer tip a little farther (~0.5 mm)
    assert ee_l[0, 2] - ee_b[0, 2] == pytest.approx(0.1, abs=5e-4)
    assert np.allclose(ee_l[0, :2], ee_b[0, :2], atol=1.0e-3)
    # throughout the motion the longer arm's tip follows its own rigid kinematics within the elastic sag
    # (the soft default plant: hub springs and blades sag up to ~3.5 cm on this 0.94 m arm)
    p_long = load_robot(longer)
    assert np.abs(ee_l - fk_ee(long_[:, 1:4], p_long)).max() < 0.045
    assert np.abs(ee_l - fk_ee(long_[:, 1:4], load_robot_params())).max() > 0.08
    # the default run is unchanged by exporting and reading back the packaged robot
    same = _ptp(tmp_path, "same", "--robot", path)
    assert np.allclose(same, base)


# ----------------------------------------------------------------------------------------- --robot everywhere

COMMANDS = [
    ["sim", "ptp", "--out", "x.csv"],
    ["sim", "record", "rgbd-disc", "--out", "x"],
    ["sim", "modes", "--at", "0,45,-45", "--out", "x.json"],
    ["servo", "--sim", "--out", "x"],
    ["catch", "demo"],
    ["calib", "rgbd-base", "seq", "--seed", "1,2"],
    ["calib", "base-stereo", "--out", "x.yaml"],
    ["demo"],
    ["joint", "serve", "--port", "0"],
    ["joint", "move", "--port", "1", "--to", "0,90,0"],
    ["robot", "export-urdf", "--out", "x.urdf"],
]


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: " ".join(a[:2]))
def test_every_kinematic_command_takes_robot(argv):
    args = build_parser().parse_args(argv + ["--robot", "a.urdf", "--robot", "b.yaml"])
    assert args.robot == ["a.urdf", "b.yaml"]
    assert build_parser().parse_args(argv).robot is None


def test_base_stereo_keeps_robot_params_alias():
    args = build_parser().parse_args(["calib", "base-stereo", "--out", "x", "--robot-params", "r.yaml"])
    assert args.robot == ["r.yaml"]


@pytest.mark.parametrize("argv", [
    ["sim", "ptp", "--duration", "0.01"],
    ["sim", "record", "rgbd-disc", "--small"],
    ["sim", "modes", "--at", "0,45,-45"],
    ["servo", "--sim"],
    ["catch", "demo", "--throws", "1"],
    ["demo"],
], ids=lambda a: " ".join(a[:2]))
def test_bad_robot_file_is_one_line_exit_2(tmp_path, capsys, argv):
    bad = tmp_path / "bad.yaml"
    bad.write_text(YAML_TEXT.replace("link2_length_m: 0.430", "link2_length_m: -1"))
    code = main(argv + ["--out", str(tmp_path / "o"), "--robot", str(bad)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and str(bad) in err and "kinematics.link2_length_m" in err
    assert not (tmp_path / "o").exists() or argv[0] == "servo"


def test_two_yamls_are_refused(capsys):
    code = main(["robot", "check", "--robot", str(DEFAULT_PARAMS_PATH), "--robot", str(DEFAULT_PARAMS_PATH)])
    assert code == 2 and "one URDF and one YAML" in capsys.readouterr().err
