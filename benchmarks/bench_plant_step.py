"""Benchmark: the catch demo's 2 kHz loop (plant, joint layer, model-assisted damper) against its former path.

The catch sessions spend nearly all their time in the simulated arm and the joint layer at 2 kHz (the agent,
the EKF and the scoring are a few per cent). Two fast paths keep the numbers and cut the cost:

* ``ModalBasis.shape_at`` remembers the mode-shape row at the arm's fixed probe points (the end effector for
  the balls in the net) instead of evaluating the hyperbolic functions at every step;
* ``StrainDynamicsModel.predict_one`` evaluates the model-assisted damper's strain prediction for one sample
  without the array checks and stacking of ``predict``.

The peer is the former path in the same process and run: ``shape_at`` replaced by ``shape([x])[:, 0]`` and the
damper given the model through ``predict`` alone. Both run the same serial catch sessions (no rendering); the
script checks that the two runs' ``throws.csv`` and ``summary.json`` are byte-identical and prints the wall times
and the ratio.

Run: ``.venv/bin/python benchmarks/bench_plant_step.py [--throws 10] [--seed 5] [--repeat 2]``
(exit status 1 when the outputs differ).
"""
from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

from _machine import cpu_model
from tudorvision.joint.strain_dynamics import StrainDynamicsModel
from tudorvision.lab.catch import DemoOptions, run_sessions
from tudorvision.sim.beam import ModalBasis

__all__ = ["former_path", "run_once", "main"]


@contextlib.contextmanager
def former_path():
    """The peer: mode-shape rows evaluated at every call, the strain model reached through ``predict`` only."""
    saved = (ModalBasis.shape_at, StrainDynamicsModel.predict_one)
    ModalBasis.shape_at = lambda self, x: self.shape([float(x)])[:, 0]
    StrainDynamicsModel.predict_one = property(lambda self: None)   # getattr(model, "predict_one") is None
    try:
        yield
    finally:
        ModalBasis.shape_at, StrainDynamicsModel.predict_one = saved


def run_once(out: Path, throws: int, seed: int) -> float:
    """Run the serial catch sessions (5 throws each) into ``out``; return the wall seconds."""
    opts = DemoOptions(throws=throws, seed=seed, render=False)
    t0 = time.perf_counter()
    run_sessions(out, opts, session_throws=5, scheduler="serial")
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--throws", type=int, default=10)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=2, help="runs of each path (the best is reported)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        run_once(d / "warm", 5, args.seed)          # calibration read, imports, caches: not timed
        best = {"former path (peer)": float("inf"), "fast paths": float("inf")}
        for k in range(args.repeat):
            with former_path():
                best["former path (peer)"] = min(best["former path (peer)"],
                                                  run_once(d / f"peer{k}", args.throws, args.seed))
            best["fast paths"] = min(best["fast paths"], run_once(d / f"fast{k}", args.throws, args.seed))
        same = all((d / "peer0" / f).read_bytes() == (d / f"fast{args.repeat - 1}" / f).read_bytes()
                   for f in ("throws.csv", "summary.json"))
    print(f"machine: {cpu_model()}, one process")
    for name, wall in best.items():
        print(f"{name:20s} {wall:7.2f} s for {args.throws} throws ({wall / args.throws:.2f} s per throw)")
    print(f"ratio (peer / ours)  {best['former path (peer)'] / best['fast paths']:.2f}x")
    print(f"throws.csv and summary.json byte-identical: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
