"""The virtual lab: wires the simulated plant and cameras to perception and the joint layer.

``lab`` is the only place where the simulation (:mod:`tudorvision.sim`), the
perception code (stereo, rgbd, servo, catch) and the joint-control layer
(:mod:`tudorvision.joint`) meet:

* :mod:`.simulation`: the elastic arm under the joint cascade (``simulate_ptp``)
  and :class:`SimCore`, the joint layer's core around the simulated arm;
* :mod:`.record`: rendered stereo and RGB-D recordings with ground truth
  (``tudorvision sim record``);
* :mod:`.lockstep`: the real server and adapter advanced in simulated time;
* :mod:`.servo_lab`, :mod:`.servo_experiments`: closed-loop visual servoing and
  the repeatability study of section 9.1;
* :mod:`.catch_demo`, :mod:`.data_collection`: the ball-catching demo of
  section 9.3 and the settled-pose collection behind its kinematics;
* :mod:`.demo`: the embedded demo (``tudorvision demo``).

Perception and the joint layer never import ``lab`` or ``sim``; the test
suite checks it with import-linter.
"""
from .lockstep import LockstepLayer
from .record import KINDS, RecordOptions, record
from .simulation import SimCore, run_recorded, simulate, simulate_ptp

__all__ = ["KINDS", "RecordOptions", "record", "LockstepLayer", "SimCore", "run_recorded", "simulate", "simulate_ptp"]
