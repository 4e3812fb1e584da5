"""The ``--robot FILE`` option shared by every command that uses TUDOR's kinematics or dynamics."""
from __future__ import annotations

import argparse

from .._checks import TudorVisionError

__all__ = ["add_robot_option", "robot_from_args", "ROBOT_HELP"]

ROBOT_HELP = ("robot description: a robot YAML, or a URDF for the rigid chain (with a robot YAML given as a "
              "second --robot for everything else); default the packaged TUDOR file; see docs/own_hardware.md")


def add_robot_option(parser: argparse.ArgumentParser, what: str | None = None, *,
                     legacy_alias: str | None = None) -> None:
    """Add ``--robot FILE`` (repeatable: one URDF plus one YAML) to a subcommand's parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    what : str, optional
        What the command takes from the robot description, appended to the help text.
    legacy_alias : str, optional
        An older option name (like ``--robot-params``) that keeps working, hidden from ``--help``.

    Returns
    -------
    None
        ``args.robot`` is None or the list of given files.
    """
    text = ROBOT_HELP + (f". Used for: {what}" if what else "")
    parser.add_argument("--robot", action="append", default=None, metavar="FILE", help=text)
    if legacy_alias:
        parser.add_argument(legacy_alias, dest="robot", action="append", metavar="FILE", help=argparse.SUPPRESS)


def robot_from_args(args: argparse.Namespace):
    """The robot parameters selected by ``--robot`` (the packaged TUDOR file when absent).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of a parser given :func:`add_robot_option`.

    Returns
    -------
    tudorvision.robot.RobotParams
        From the YAML, or from the URDF (rigid chain) and the YAML or the packaged defaults
        (everything else).

    Raises
    ------
    TudorVisionError
        For a bad file (one line naming the file and the key, line or joint), or for more
        than one URDF and one YAML.
    """
    from ..robot import is_urdf, load_robot, load_robot_params
    files = getattr(args, "robot", None) or []
    if isinstance(files, str):
        files = [files]
    if not files:
        return load_robot_params()
    urdfs = [f for f in files if is_urdf(f)]
    yamls = [f for f in files if f not in urdfs]
    if len(files) > 2 or len(urdfs) > 1 or len(yamls) > 1:
        raise TudorVisionError(f"--robot {' '.join(map(str, files))}: give one robot YAML, one URDF, "
                               "or one URDF and one YAML (rigid chain from the URDF, the rest from the YAML)")
    if urdfs:
        return load_robot(urdfs[0], elastic=yamls[0] if yamls else None)
    return load_robot(yamls[0])
