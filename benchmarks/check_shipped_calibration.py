"""Maintainer check: the catch demo's shipped wall-camera calibration and strain model against fresh ones.

With it, the wall camera's depth-pattern calibration (``depth_pattern_<key>.yaml``, 30 rendered wall frames, about
9 s), which the calibration and every demo read: compared bit for bit, shipped with ``--ship`` under today's key.
And the strain model the demo's layer uses (``strain_model_<key>.npz``, chapter 10's identification on the demo's
plant, four APRBS runs of 40 s, about 1-2 min): identified afresh and compared by the strains it predicts
(:func:`tudorvision.lab.ch10.check_shipped_strain_model`; its code hash is
:func:`tudorvision.lab.ch10.identification_code_hash`, over
:data:`tudorvision.lab.ch10.IDENTIFICATION_CODE_FILES`, checked by ``tests/test_catch_damping_model.py``).

The default placement's calibration ships in ``tudorvision/catch/data/wall_calibration_<key>.npz``
so that ``make demo`` and every experiment read it instead of rendering and tracking the
2400-frame disc sweep (about 3 min on one core). The shipped file names the code that computed it
(:func:`tudorvision.lab.catch.calibration.calibration_code_hash`); ``make test`` checks that it is
today's code (``tests/test_catch_calibration_cache.py``) and that the hash covers every file whose code
runs in a calibration. This script does the slow part: it computes the calibration afresh, prints the
largest difference to the shipped transform, and with ``--ship`` replaces the shipped file. Run it after
any change to :data:`tudorvision.lab.catch.calibration.CODE_FILES` or
:data:`tudorvision.lab.ch10.IDENTIFICATION_CODE_FILES` (a test then fails) and after a change of numpy, SciPy
or OpenCV.

    .venv/bin/python benchmarks/check_shipped_calibration.py            # compare; exit 1 on a difference
    .venv/bin/python benchmarks/check_shipped_calibration.py --ship     # compute and ship anew (within --atol of
                                                                        # the shipped: only the code hash replaced;
                                                                        # the strain model likewise within 1e-3)

Exit status: 0 when the shipped files are this code's and agree (or were shipped), 1 otherwise.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time


def main(argv=None) -> int:
    """Compare (and with ``--ship`` replace) the shipped calibration; returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ship", action="store_true", help="write the fresh calibration into the package data")
    ap.add_argument("--atol", type=float, default=1e-9,
                    help="largest difference of T_base_cam accepted (default 1e-9)")
    args = ap.parse_args(argv)

    import numpy as np

    from tudorvision.lab.catch.calibration import check_shipped_calibration, ship_depth_pattern
    from tudorvision.lab.catch.run import demo_kinematics
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.lab.catch_demo import DemoOptions
    from tudorvision.lab.ch10 import check_shipped_strain_model
    from tudorvision.lab.data_collection import plant_config
    from tudorvision.robot import load_robot_params

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        options, params = DemoOptions(render=False, cache_dir=tmp), load_robot_params()
        world = CatchScenario(options, params, np.deg2rad([0.0, 90.0, 0.0]))
        T_true, cam = world.T_base_cam, world.camera                                         # the throws' camera
        pattern = ship_depth_pattern(options, cam.K, cam.width, cam.height, ship=args.ship)
        res = check_shipped_calibration(options, params, T_true, tmp, ship=args.ship, atol=args.atol,
                                        deflection=demo_kinematics(options, params)[0].deflection)
    res["depth_pattern"] = pattern
    model = check_shipped_strain_model(plant_config(DemoOptions().plant), ship=args.ship)
    res["strain_model"] = model
    res["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(res, indent=1))
    if args.ship:
        return 0
    same = res["shipped"] and res["shipped_code"] == res["code"] and res["max_abs_difference"] <= args.atol \
        and pattern["shipped"] and pattern["max_abs_difference"] == 0.0 \
        and model["shipped"] and model["same"] and model["shipped_code"] == model["code"]
    if not same:
        print("the shipped calibration or strain model is not this code's: run with --ship", file=sys.stderr)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
