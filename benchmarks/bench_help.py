"""Time of ``tudorvision --help`` and ``tudorvision <cmd> --help`` against the interpreter's own start-up.

Run: ``.venv/bin/python benchmarks/bench_help.py [--repeat N] [--tree DIR]``. Not a test.

The peer is ``python -c "import numpy"`` (the floor: start-up plus numpy, which
the argument checks need); ``--tree DIR`` also times another checkout of the
package (e.g. a ``git worktree`` of an older commit) in the same run.
Prints the median wall time of each and the ratio to the peer.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _machine import cpu_model

COMMANDS = (["--help"], ["sim", "--help"], ["track", "stereo", "--help"], ["calib", "rgbd-base", "--help"],
            ["joint", "move", "--help"], ["catch", "--help"], ["servo", "--help"])


def _time(argv, env, repeat, cwd=None):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(argv, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--tree", default=None, help="another checkout to time in the same run (its repo root)")
    args = ap.parse_args()
    env = dict(os.environ)
    peer = _time([sys.executable, "-c", "import numpy"], env, args.repeat)
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores; median of {args.repeat}")
    print(f"peer   python -c 'import numpy': {peer:.3f} s")
    here = Path(__file__).resolve().parents[1]
    trees = [("this tree", here)] + ([(args.tree, Path(args.tree).resolve())] if args.tree else [])
    for label, root in trees:
        tenv = dict(env, PYTHONPATH=str(root))
        for cmd in COMMANDS:
            t = _time([sys.executable, "-m", "tudorvision.cli", *cmd], tenv, args.repeat, cwd=root)
            print(f"{label:>12s}  tudorvision {' '.join(cmd):24s} {t:.3f} s  ratio to peer {t / peer:.2f}")


if __name__ == "__main__":
    main()
