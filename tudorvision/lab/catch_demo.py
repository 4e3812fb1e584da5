"""The ball-catching demo (section 9.3): the names of :mod:`tudorvision.lab.catch`, where it lives.

Kept so that ``from tudorvision.lab.catch_demo import DemoOptions, run_demo``
(the CLI, benchmarks, notebooks) goes on working. The demo is split into
scenario (ground truth), agent (perception and the joint layer's adapter
only), scorer and writers; see :mod:`tudorvision.lab.catch`.
"""
from .catch import (PER_THROW_COLUMNS, WEIGH_REST_SPEED_RAD_S, DemoOptions, ThrowResult, demo_kinematics,
                    pause_and_weigh, run_demo, simulated_detection)

__all__ = ["DemoOptions", "simulated_detection", "run_demo", "demo_kinematics", "PER_THROW_COLUMNS",
           "ThrowResult", "WEIGH_REST_SPEED_RAD_S", "pause_and_weigh"]
