"""``tudorvision robot``: the robot description (export TUDOR's rigid chain as URDF, check a file)."""
from __future__ import annotations

from .robot_args import add_robot_option, robot_from_args

__all__ = ["register"]


def _cmd_export_urdf(args) -> int:
    from ..io.atomic import write_text_atomic
    from ..robot import urdf_from_params
    params = robot_from_args(args)
    write_text_atomic(args.out, urdf_from_params(params, name=args.name))
    print(f"wrote {args.out} (rigid chain: link1 height {params.link1_height_m:.4g} m, links "
          f"{params.link2_length_m:.4g} m and {params.link3_length_m:.4g} m)")
    return 0


def _cmd_check(args) -> int:
    import numpy as np
    params = robot_from_args(args)
    lim = np.round(np.rad2deg(params.joint_limits_rad), 2).tolist()
    print(f"ok: link1 height {params.link1_height_m:.4g} m, link2 {params.link2_length_m:.4g} m, "
          f"link3 {params.link3_length_m:.4g} m, joint ranges {lim} deg")
    return 0


def register(sub) -> None:
    p = sub.add_parser("robot", help="robot description: export TUDOR as URDF, check a YAML or URDF",
                       description="The robot description every kinematic command reads with --robot FILE "
                                   "(docs/own_hardware.md).")
    s = p.add_subparsers(dest="robot_command", metavar="ACTION")
    e = s.add_parser("export-urdf", help="write the rigid chain (default: packaged TUDOR) as a URDF",
                     description="Write the rigid chain of the robot description as URDF: links base_link, "
                                 "link1..link3, ee; revolute joint1..joint3 with ranges, speeds and torque limits.")
    e.add_argument("--out", required=True, help="URDF output file")
    e.add_argument("--name", default="tudor", help="robot name in the URDF (default tudor)")
    add_robot_option(e, "the chain to export")
    e.set_defaults(func=_cmd_export_urdf)
    c = s.add_parser("check", help="load a robot YAML or URDF and print its rigid chain (or the error)")
    add_robot_option(c, "the file to check")
    c.set_defaults(func=_cmd_check)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
