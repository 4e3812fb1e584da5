"""The ``tudorvision`` command.

Each module of this package that offers commands has a function
``register(subparsers)`` that adds its subcommands; every subcommand sets
``func`` to a callable taking the parsed ``argparse.Namespace`` and returning
an exit code. User mistakes raise :class:`TudorVisionError` (or ``ValueError``
/ ``OSError``: a missing file, a full disk, a read-only folder) and are printed
as one line naming the file with exit code 2; Ctrl-C exits with 130.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .. import __version__
from .._checks import TudorVisionError
from ..joint.cores import register_core

__all__ = ["main", "build_parser"]

# Modules providing subcommands, in --help order.
COMMAND_MODULES = (
    "tudorvision.cli.sim",
    "tudorvision.cli.seq",
    "tudorvision.cli.calib",
    "tudorvision.cli.stereo",
    "tudorvision.cli.rgbd",
    "tudorvision.cli.servo",
    "tudorvision.cli.catch",
    "tudorvision.cli.joint",
    "tudorvision.cli.demo",
    "tudorvision.cli.label",
    "tudorvision.cli.robot",
    "tudorvision.cli.reproduce",
)


def _sim_core(**options):
    """The virtual lab's simulated elastic TUDOR as a joint-layer core (imported on first use)."""
    from ..lab.simulation import SimCore
    return SimCore(**options)


register_core("sim", _sim_core)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="tudorvision",
        description="Perception for the elastic-link arm TUDOR: stereo tracking, RGB-D calibration, "
                    "visual servoing, ball catching, and a virtual lab to test them on.")
    parser.add_argument("--version", action="version", version=f"tudorvision {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:   # command module not part of this build
                continue
            raise
        mod.register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2 if args.command is None else 0
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("tudorvision: interrupted", file=sys.stderr)
        return 130
    except (TudorVisionError, ValueError, OSError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, OSError) and exc.strerror:
            msg = f"{exc.filename or 'file'}: {exc.strerror.lower()}"
        print(f"tudorvision {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
