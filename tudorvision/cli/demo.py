"""``tudorvision demo``: the virtual lab end to end (:func:`tudorvision.lab.demo.run_demo`)."""
from __future__ import annotations

from .robot_args import add_robot_option, robot_from_args

__all__ = ["register"]


def _cmd_demo(args) -> int:
    from ..lab.demo import run_demo
    run_demo(args.out, seed=args.seed, params=robot_from_args(args) if args.robot else None)
    return 0


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the embedded demo (virtual lab end to end)",
                       description="Run the virtual lab end to end on an embedded default and write plots, "
                                   "recordings and a summary.")
    p.add_argument("--out", default="out/demo", help="output directory (default out/demo)")
    p.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    add_robot_option(p, "the simulated arm of every part of the demo")
    p.set_defaults(func=_cmd_demo)
