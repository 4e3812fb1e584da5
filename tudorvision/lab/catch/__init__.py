"""The ball-catching demo in the virtual lab (section 9.3), in four parts.

* :mod:`.scenario`: the world the agent must not see: thrower, throws and their
  ground truth, the simulated arm behind the joint layer, the wall RGB-D camera
  (rendered frames or the detection-noise model), the operator who empties the net;
* :mod:`.agent`: the catching side: ball detector, EKF and intercept
  (:class:`~tudorvision.catch.perception.CatchPerception`), compensated inverse
  kinematics, commands and payload through the joint layer's adapter only;
* :mod:`.score`: caught or missed, and why, from ground truth
  (:class:`~.score.ThrowResult`, one per throw) and the run's summary;
* :mod:`.writers`: ``throws.csv``, ``predictions.csv``, ``setpoints.csv``,
  ``summary.json``, ``catch.png`` and ``catch.rrd``;
* :mod:`.calibration`: the wall camera's ``T_base_cam`` from a simulated disc
  sweep with the camera where it stands for the throws (the perception of
  ``calib rgbd-base``; the true transform only with ``DemoOptions.true_calibration``);

:func:`~.run.run_demo` wires them (``tudorvision catch demo``); its options are
:class:`~.options.DemoOptions`. :mod:`.sessions` splits many throws into
independent sessions on the experiment runner (``catch demo --scheduler ...``);
:func:`~.reproduce_rows.catch_success` is the success-rate row of ``tudorvision reproduce``.
"""
from .agent import WEIGH_REST_SPEED_RAD_S, CatchAgent, ReferenceMirror, pause_and_weigh
from .planes import CatchIK
from .options import PLANTS, DemoOptions, plant_config, trained_payload_range_kg
from .reproduce_rows import catch_success
from .run import demo_kinematics, run_demo
from .scenario import CatchScenario, simulated_detection, true_crossing
from .score import PER_THROW_COLUMNS, ThrowResult, summarize_throws
from .sessions import plan_sessions, run_sessions

__all__ = ["DemoOptions", "run_demo", "demo_kinematics", "simulated_detection", "PER_THROW_COLUMNS", "ThrowResult",
           "summarize_throws", "trained_payload_range_kg", "CatchScenario", "CatchAgent", "CatchIK",
           "pause_and_weigh", "true_crossing", "WEIGH_REST_SPEED_RAD_S", "plan_sessions", "run_sessions",
           "PLANTS", "plant_config", "ReferenceMirror", "catch_success"]
