"""``tudorvision joint`` commands: serve the layer on loopback, query it, move it.

* ``joint keygen --out KEY`` writes a random key file (permissions 0600);
* ``joint serve --port P [--duration S] [--core NAME] [--key-file KEY] [--host H]``
  runs the joint-control layer in real time (on 127.0.0.1 unless ``--host``;
  any other address needs ``--key-file``) and prints the address it listens on;
* ``joint status --port P [--timeout S]`` prints the layer's state (exit 0),
  or one line and exit 1 when nothing answers;
* ``joint move --port P --to DEG,DEG,DEG`` sends a setpoint and waits until
  the arm has settled (exit 0), printing a status line every ``--progress``
  seconds (joint angles, distance to the goal, link-tip oscillation, elapsed
  time); exit 1 on refusal, silence or timeout, with the reason it did not
  settle (a joint still on its way or stopped short, a fault, a collision, or
  link oscillation with the damping law in use and what to try);
* ``joint payload --port P --kg M`` tells the layer the end-effector payload
  (its damping gains and collision model follow it); exit 1 on refusal or silence.

``status``, ``move`` and ``payload`` take ``--key-file`` (a layer served with a
key answers nothing else) and ``--host``; ``move`` and ``payload`` open a
session (the lease) for their command and release it, ``--takeover`` takes it
from another client. Angles on the command line are in degrees; everything
inside is SI.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import deque

import numpy as np

from ._viewer import add_viewer_arguments, open_viewer
from .robot_args import add_robot_option, robot_from_args

__all__ = ["register", "tip_mm_per_strain"]


def _port(allow_zero: bool):
    def parse(text: str) -> int:
        try:
            port = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer port, got {text!r}") from None
        low = 0 if allow_zero else 1
        if not low <= port <= 65535:
            raise argparse.ArgumentTypeError(f"expected a port in {low}..65535, got {port}")
        return port
    return parse


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (np.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _robot_arg(parser, what: str) -> None:
    add_robot_option(parser, what)


def _robot_params(args):
    return robot_from_args(args)


def _mass(text: str) -> float:
    from .._checks import check_mass
    try:
        return check_mass(text, "mass")
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _degrees3(text: str) -> np.ndarray:
    parts = text.split(",")
    try:
        deg = np.array([float(p) for p in parts])
    except ValueError:
        deg = None
    if deg is None or deg.shape != (3,) or not np.all(np.isfinite(deg)):
        raise argparse.ArgumentTypeError(
            f"expected three comma-separated angles in degrees (e.g. 0,90,0), got {text!r}")
    return deg


def _damping_names():
    from ..joint.protocol import Damping
    return list(Damping)


def _key_arg(parser, what: str) -> None:
    parser.add_argument("--key-file", default=None, metavar="KEY",
                        help=f"key file written by 'tudorvision joint keygen': {what}")


def _peer_args(parser, session: bool = False) -> None:
    parser.add_argument("--port", type=_port(False), required=True, help="UDP port of the layer")
    parser.add_argument("--host", default="127.0.0.1", help="address of the layer (default 127.0.0.1)")
    _key_arg(parser, "the layer's key, if it was served with one")
    if session:
        parser.add_argument("--takeover", action="store_true",
                            help="take the lease from the client holding it (the layer stops the arm first)")


def _read_key(args):
    from ..joint.protocol import read_key_file
    return None if args.key_file is None else read_key_file(args.key_file)


def register(subparsers) -> None:
    """Add the ``joint`` command and its actions to the top-level parser."""
    p = subparsers.add_parser("joint", help="joint-control layer over UDP: serve, status, move, payload",
                              description=__doc__.split("\n\n")[0])
    actions = p.add_subparsers(dest="joint_action", metavar="ACTION")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])

    k = actions.add_parser("keygen", help="write a random key file (0600) for authenticated serving")
    k.add_argument("--out", required=True, metavar="KEY", help="key file to create")
    k.add_argument("--force", action="store_true", help="replace an existing key file")
    k.set_defaults(func=_keygen)

    s = actions.add_parser("serve", help="run the joint-control layer (on 127.0.0.1 by default)")
    s.add_argument("--port", type=_port(True), required=True,
                   help="UDP port (0 picks a free one; printed on start)")
    s.add_argument("--host", default="127.0.0.1",
                   help="address to bind (default 127.0.0.1); anything but loopback needs --key-file")
    _key_arg(s, "every datagram must carry an HMAC-SHA256 tag made with this key")
    s.add_argument("--duration", type=_positive, default=None,
                   help="stop after this many seconds (default: until interrupted)")
    s.add_argument("--core", default="kinematic", help="registered core (default: kinematic)")
    s.add_argument("--rate", type=_positive, default=500.0, help="control rate in Hz")
    s.add_argument("--watchdog", type=_positive, default=0.1,
                   help="velocity command lifetime in s (default 0.1)")
    s.add_argument("--collision-model", default=None, metavar="DIR",
                   help="core sim: identified strain dynamics for collision handling, a folder with chi.npy, "
                        "thr.npy and optionally coupling.npy (as written by benchmarks/bench_collision.py)")
    s.add_argument("--damping-model", default=None, metavar="CHI_NPY",
                   help="core sim: identified strain dynamics (chi.npy) for the model-assisted static "
                        "strain cancellation of the damper")
    _robot_arg(s, "joint ranges, speed and acceleration limits; core sim: the whole arm")
    s.set_defaults(func=_serve)

    st = actions.add_parser("status", help="print the layer's state")
    _peer_args(st)
    st.add_argument("--timeout", type=_positive, default=1.0, help="seconds to wait (default 1)")
    st.set_defaults(func=_status)

    m = actions.add_parser("move", help="send a joint setpoint and wait until settled")
    _peer_args(m, session=True)
    m.add_argument("--to", type=_degrees3, required=True, metavar="DEG,DEG,DEG",
                   help="target joint angles in degrees")
    m.add_argument("--speed", type=_positive, default=None, metavar="DEG_S",
                   help="profile speed in deg/s (default: the layer's, 60)")
    m.add_argument("--accel", type=_positive, default=None, metavar="DEG_S2",
                   help="profile acceleration in deg/s^2 (default: the layer's, 200)")
    m.add_argument("--tol", type=_positive, default=0.5, metavar="DEG",
                   help="settling tolerance in degrees (default 0.5)")
    m.add_argument("--timeout", type=_positive, default=20.0,
                   help="seconds to wait for the arm to settle (default 20)")
    m.add_argument("--joints-only", action="store_true",
                   help="wait for the joints only, not for the link vibrations to decay")
    m.add_argument("--damping", choices=[d.name.lower() for d in _damping_names()],
                   default=None, help="also switch the damping law (default: keep)")
    m.add_argument("--progress", type=_non_negative, default=1.0, metavar="S",
                   help="seconds between status lines while waiting (default 1; 0: none)")
    _robot_arg(m, "link lengths and blades, to turn the strain gauges into link-tip oscillation in mm")
    add_viewer_arguments(m, file_help="rerun recording (.rrd) of joint angles, speeds, strains and the setpoint "
                                      "while waiting")
    m.set_defaults(func=_move)

    pl = actions.add_parser("payload", help="tell the layer the end-effector payload")
    _peer_args(pl, session=True)
    pl.add_argument("--kg", type=_mass, required=True, metavar="KG",
                    help="payload at the end effector in kg (mount, plates, caught balls)")
    pl.add_argument("--timeout", type=_positive, default=1.0, help="seconds to wait (default 1)")
    pl.set_defaults(func=_payload)


def _load_npy(path: str, what: str, shape=None) -> np.ndarray:
    from .._checks import TudorVisionError
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
        a = np.load(path, allow_pickle=False) if magic == b"\x93NUMPY" else None
    except (OSError, ValueError) as err:
        raise TudorVisionError(f"{what}: cannot read {path}: {err}") from None
    if a is None:
        raise TudorVisionError(f"{what}: {path} is not a NumPy .npy file")
    if shape is not None and a.shape != shape:
        raise TudorVisionError(f"{what}: {path} holds an array of shape {a.shape}, expected {shape}")
    if a.dtype.kind not in "iuf":
        raise TudorVisionError(f"{what}: {path} holds {a.dtype} values, expected real numbers")
    if not np.all(np.isfinite(a)):
        raise TudorVisionError(f"{what}: {path} holds NaN or infinite values")
    return a


def _core_options(args) -> dict:
    """Model files of ``joint serve`` as :class:`SimCore` options (one-line errors naming the file)."""
    import os

    from .._checks import TudorVisionError
    from ..joint.collision import ResidualCoupling
    from ..joint.strain_dynamics import N_PARAMS, StrainDynamicsModel
    opts = {}
    if (args.collision_model or args.damping_model) and args.core != "sim":
        raise TudorVisionError(f"--collision-model/--damping-model: only for --core sim, not {args.core!r}")
    chi_shape = (2, 2 * N_PARAMS)
    if args.collision_model:
        d = args.collision_model
        if not os.path.isdir(d):
            raise TudorVisionError(f"--collision-model: {d} is not a folder (expected chi.npy, thr.npy)")
        opts["collision_model"] = StrainDynamicsModel(
            chi=_load_npy(os.path.join(d, "chi.npy"), "--collision-model", chi_shape))
        opts["collision_thresholds"] = _load_npy(os.path.join(d, "thr.npy"), "--collision-model", (2,))
        if not np.all(opts["collision_thresholds"] > 0):
            raise TudorVisionError(f"--collision-model: {os.path.join(d, 'thr.npy')}: thresholds must be > 0, got "
                                   f"{opts['collision_thresholds'].tolist()}")
        cp = os.path.join(d, "coupling.npy")
        if os.path.exists(cp):
            opts["collision_coupling"] = ResidualCoupling(*_load_npy(cp, "--collision-model", (3,)))
        note = collision_model_mismatch(os.path.join(d, "collision.json"))
        if note:
            print(f"warning: --collision-model: {note}", file=sys.stderr)
        opts["collision_transient_gain"] = collision_transient_gain(os.path.join(d, "collision.json"))
    if args.damping_model:
        opts["damping_model"] = StrainDynamicsModel(
            chi=_load_npy(args.damping_model, "--damping-model", chi_shape))
    return opts


def _keygen(args) -> int:
    from ..joint.protocol import write_key_file
    write_key_file(args.out, overwrite=args.force)
    print(f"key written to {args.out} (permissions 0600); give it to the layer and its clients only")
    return 0


def _serve(args) -> int:
    import ipaddress

    from .._checks import TudorVisionError
    from ..joint.server import JointLayerServer, ServerConfig, make_core
    from ..joint.transport import UdpTransport

    key = _read_key(args)
    try:
        loopback = ipaddress.ip_address(args.host).is_loopback
    except ValueError:
        loopback = args.host == "localhost"
    if key is None and not loopback:
        raise TudorVisionError(f"--host {args.host}: serving beyond loopback needs --key-file "
                               f"(tudorvision joint keygen --out KEY)")
    from ..joint.safety import SafetyLimits
    params = _robot_params(args)
    limits = SafetyLimits.from_params(params)
    options = _core_options(args)
    if args.robot is not None:
        options.update(params=params) if args.core == "sim" else options.update(limits=limits)
    core = make_core(args.core, **options)
    try:
        transport = UdpTransport.server(port=args.port, host=args.host)
    except OSError as err:
        raise TudorVisionError(f"--host {args.host} --port {args.port}: cannot bind: {err.strerror}") from None
    with transport:
        server = JointLayerServer(transport, core, key=key, limits=limits,
                                  config=ServerConfig(rate_hz=args.rate,
                                                      watchdog_s=args.watchdog))
        host, port = transport.address
        auth = "HMAC-SHA256" if key is not None else "no key, loopback only"
        print(f"joint layer (core {args.core}, {auth}) listening on udp {host}:{port}", flush=True)
        if args.duration is None:
            server.serve_forever()
        else:
            server.run_for(args.duration)
    return 0


def _format_state(st) -> str:
    deg = np.rad2deg
    flags = "|".join(f.name for f in type(st.flags) if f and f in st.flags) or "none"
    c = st.counters
    lines = [
        f"t {st.t:.3f} s  mode {st.mode.name}  damping {st.damping.name}  "
        f"collision {st.collision.name}",
        "theta_deg " + " ".join(f"{x:8.3f}" for x in deg(st.theta)),
        "theta_dot_deg_s " + " ".join(f"{x:8.3f}" for x in deg(st.theta_dot)),
        "strains_um_m " + " ".join(f"{x * 1e6:8.2f}" for x in st.strains),
        "residuals " + " ".join(f"{x:.4g}" for x in st.residuals),
        f"flags {flags}  last_command_seq {st.last_command_seq}",
        f"counters accepted={c.accepted} refused={c.refused} malformed={c.malformed} "
        f"duplicates={c.duplicates} stale={c.stale} watchdog_stops={c.watchdog_stops} "
        f"overruns={c.overruns}",
        f"security unauthenticated={c.unauthenticated} replayed={c.replayed} "
        f"rate_limited={c.rate_limited} not_owner={c.not_owner} faults={c.faults}",
        f"tick_interval_ms p50 {st.tick_p50_s * 1e3:.3f} p99 {st.tick_p99_s * 1e3:.3f} "
        f"max {st.tick_max_s * 1e3:.3f} (last second)",
    ]
    return "\n".join(lines)


_KEY_HINT = " (nothing listening, or a layer with another key: see --key-file)"


def _client(args):
    from ..joint.adapter import JointAdapter
    from ..joint.transport import UdpTransport
    return JointAdapter(UdpTransport.client(args.port, host=args.host), key=_read_key(args),
                        takeover=getattr(args, "takeover", False))


def _fail(action: str, text: str) -> int:
    print(f"tudorvision joint {action}: {text}", file=sys.stderr)
    return 1


def _status(args) -> int:
    with _client(args) as joints:
        st = joints.request_state(timeout=args.timeout)
    if st is None:
        return _fail("status", f"no answer from {args.host}:{args.port} within {args.timeout:g} s"
                               f"{_KEY_HINT}")
    print(_format_state(st))
    return 0


def _payload(args) -> int:
    from ..joint.protocol import Ack

    with _client(args) as joints:
        reply = joints.set_payload(args.kg, timeout=args.timeout)
    if reply is None:
        return _fail("payload", f"no answer from {args.host}:{args.port} within {args.timeout:g} s"
                                f"{_KEY_HINT}")
    if not isinstance(reply, Ack):
        return _fail("payload", f"refused: {reply.code.name} {reply.text}")
    print(f"payload {args.kg:g} kg accepted")
    return 0


def _move(args) -> int:
    from ..joint.protocol import Ack, Damping, Mode

    target = np.deg2rad(args.to)
    speed = None if args.speed is None else float(np.deg2rad(args.speed))
    accel = None if args.accel is None else float(np.deg2rad(args.accel))
    with _client(args) as joints:
        damping = None if args.damping is None else Damping[args.damping.upper()]
        reply = joints.set_mode(Mode.SETPOINT, damping=damping, timeout=min(args.timeout, 2.0))
        if reply is None:
            return _fail("move", f"no answer from {args.host}:{args.port}{_KEY_HINT}")
        if not isinstance(reply, Ack):
            return _fail("move", f"mode switch refused: {reply.code.name} {reply.text}")
        reply = joints.send_setpoint(target, max_speed=speed, max_accel=accel,
                                     timeout=min(args.timeout, 2.0))
        if reply is None:
            return _fail("move", f"no answer to the setpoint from {args.host}:{args.port}")
        if not isinstance(reply, Ack):
            return _fail("move", f"setpoint refused: {reply.code.name}: {reply.text}")
        if reply.text:
            print(f"note: {reply.code.name}: {reply.text}")
        viewer = open_viewer(args, "tudorvision_joint_move")
        try:
            st, why = _wait_with_progress(joints, target, args, recording=None if viewer is None else viewer.rec)
        finally:
            if viewer is not None:
                viewer.close()
    if st is None:
        return _fail("move", f"did not settle at {_deg_text(args.to)} deg within {args.timeout:g} s: {why}")
    print("settled at theta_deg " + " ".join(f"{x:.3f}" for x in np.rad2deg(st.theta)))
    return 0


def _deg_text(deg) -> str:
    return ",".join(f"{x:g}" for x in np.asarray(deg, float))


def tip_mm_per_strain(params) -> np.ndarray:
    """Link-tip deflection per unit root-gauge strain of links 2 and 3, mm per m/m.

    A cantilever blade bent by a force at its tip (the first bending mode,
    statically): the strain at the gauge ``x`` from the root is
    ``F (L - x) (h / 2) / (E I)`` and the tip deflection ``F L^3 / (3 E I)``,
    so the deflection is ``2 L^3 / (3 h (L - x))`` times the strain.

    Parameters
    ----------
    params : tudorvision.robot.RobotParams
        Link blades (length, height) and strain-gauge positions.

    Returns
    -------
    ndarray, shape (2,)
        mm of tip deflection per m/m of strain at the root gauge of link 2 and link 3.

    Examples
    --------
    >>> from tudorvision.robot import load_robot_params
    >>> (tip_mm_per_strain(load_robot_params()) * 100e-6).round(1).tolist()   # 100 um/m at the roots
    [3.5, 3.2]
    """
    out = []
    for name in ("link2", "link3"):
        link = getattr(params, name)
        x = float(params.gauge_positions_m[name][0])
        out.append(2.0 * link.length_m ** 3 / (3.0 * link.height_m * (link.length_m - x)) * 1e3)
    return np.array(out)


def _oscillation_mm(history, mm_per_strain) -> np.ndarray:
    """Half peak-to-peak of the root strains over ``history`` as link-tip mm (links 2, 3)."""
    if len(history) < 2:
        return np.zeros(2)
    roots = np.array([[st.strains[0], st.strains[2]] for _, st in history])
    return (roots.max(axis=0) - roots.min(axis=0)) / 2.0 * mm_per_strain


def _status_line(elapsed_s, st, target, osc_mm) -> str:
    err_deg = np.rad2deg(np.abs(np.asarray(st.theta) - target))
    j = int(np.argmax(err_deg))
    return (f"{elapsed_s:5.1f} s  theta_deg " + " ".join(f"{x:8.3f}" for x in np.rad2deg(st.theta))
            + f"  to goal {err_deg[j]:.3f} deg (joint {j + 1})  link-tip oscillation "
            + "/".join(f"{x:.1f}" for x in osc_mm) + f" mm  damping {st.damping.name.lower()}")


def _why(history, target, tol, args, mm_per_strain) -> str:
    """One sentence: why the arm is not settled at ``target`` (from the last states seen)."""
    from ..joint.protocol import Damping, StateFlags

    if not history:
        return f"no state from {args.host}:{args.port} while waiting{_KEY_HINT}"
    st = history[-1][1]
    if st.flags & StateFlags.FAULT:
        return "the layer stopped the arm after a fault (see 'tudorvision joint status')"
    if st.flags & StateFlags.COLLISION:
        return "a collision was detected and the layer reacted (see 'tudorvision joint status')"
    err = np.asarray(st.theta) - target
    j = int(np.argmax(np.abs(err)))
    if abs(err[j]) > tol:
        err_deg = float(np.rad2deg(abs(err[j])))
        if st.flags & StateFlags.MOVING:
            speed = float(np.rad2deg(abs(st.theta_dot[j])))
            return (f"joint {j + 1} still {err_deg:.2f} deg from the goal, moving at {speed:.1f} deg/s; "
                    f"try a longer --timeout or a higher --speed")
        return (f"joint {j + 1} stopped {err_deg:.2f} deg from the goal (tolerance {args.tol:g} deg); "
                f"the arm may sag under its payload, try --tol or check 'tudorvision joint status'")
    if args.joints_only:
        return "the joints are at the goal but still moving (MOVING flag); try a longer --timeout"
    osc = _oscillation_mm(history, mm_per_strain)
    k = int(np.argmax(osc))
    what = f"link oscillation {osc[k]:.1f} mm on link {k + 2} (after joint {k + 2}), joints at the goal"
    if st.damping == Damping.OFF:
        return f"{what} - damping is off; try --damping proportional (or --joints-only)"
    return (f"{what} - damping {st.damping.name.lower()} has not brought the link strains into the "
            f"settling band yet; try a longer --timeout or --joints-only")


def _wait_with_progress(joints, target, args, recording=None):
    """Poll until settled at ``target``: ``(state, None)``, or ``(None, reason)`` after ``args.timeout`` s.

    Every state received is logged to ``recording`` (a rerun stream) when given.
    """
    from ..joint.protocol import StateFlags
    from ..joint.rerun_log import log_joint_state

    tol = float(np.deg2rad(args.tol))
    mm_per_strain = tip_mm_per_strain(_robot_params(args))
    t0 = time.monotonic()
    deadline = t0 + args.timeout
    next_line = t0 + args.progress if args.progress > 0 else float("inf")
    history = deque()                    # (wall time, state) over the last 2 s
    while True:
        now = time.monotonic()
        if now >= deadline:
            return None, _why(history, target, tol, args, mm_per_strain)
        st = joints.request_state(timeout=min(deadline - now, 0.5))
        now = time.monotonic()
        if st is not None:
            if recording is not None:
                log_joint_state(recording, st, target)
            history.append((now, st))
            while history and history[0][0] < now - 2.0:
                history.popleft()
            at_goal = float(np.max(np.abs(np.asarray(st.theta) - target))) <= tol
            if at_goal and (not st.flags & StateFlags.MOVING if args.joints_only else st.settled):
                return st, None
            if now >= next_line:
                print(_status_line(now - t0, st, target, _oscillation_mm(history, mm_per_strain)), flush=True)
                next_line = now + args.progress
        time.sleep(max(0.0, min(0.02, deadline - time.monotonic())))


def collision_transient_gain(meta_path) -> float:
    """The transient allowance a collision model folder was evaluated with (``collision.json``), or 0.

    Parameters
    ----------
    meta_path : str
        The folder's ``collision.json`` (``transient_gain``; absent in folders written before it existed).

    Returns
    -------
    float
        The gain, 0 when the file or the key is absent.

    Raises
    ------
    TudorVisionError
        The file is unreadable JSON, or the gain is not a number >= 0 (naming the file).
    """
    import json
    import math
    import os

    from .._checks import TudorVisionError

    if not os.path.exists(meta_path):
        return 0.0
    try:
        with open(meta_path, encoding="utf-8") as f:
            gain = json.load(f).get("transient_gain", 0.0)
        gain = float(0.0 if gain is None else gain)
    except (OSError, ValueError, TypeError, AttributeError) as e:
        raise TudorVisionError(f"--collision-model: {meta_path}: transient_gain unreadable ({e})") from None
    if not (math.isfinite(gain) and gain >= 0):
        raise TudorVisionError(f"--collision-model: {meta_path}: transient_gain must be a number >= 0, got {gain}")
    return gain


def collision_model_mismatch(meta_path) -> str | None:
    """Why a collision model folder's thresholds may not fit the served soft arm, or None.

    The thresholds hold for the plant and the damping gains they were identified with
    (``collision.json`` of ``benchmarks/bench_collision.py``: ``plant``, ``soft_k_eps``). The
    ``sim`` core runs the soft default plant with the layer's own proportional gains
    (:data:`tudorvision.joint.damping_gains.SOFT_GAINS`); a model identified on another plant or
    with other gains detects later or raises false alarms. A missing or unreadable file says nothing.

    Parameters
    ----------
    meta_path : str
        The folder's ``collision.json``.

    Returns
    -------
    str or None
        A one-line reason, or None when the file is absent, unreadable or matches.
    """
    import json

    from ..joint.damping_gains import SOFT_GAINS
    try:
        with open(meta_path, encoding="utf-8") as f:
            meta = json.load(f)
        plant = meta.get("plant")
        gains = meta.get("soft_k_eps")
    except (OSError, ValueError, AttributeError):
        return None
    layer = tuple(float(g) for g in SOFT_GAINS["proportional"])
    if plant is not None and plant != "soft":
        return (f"{meta_path} was identified on the {plant!r} plant; the sim core is the soft plant "
                f"(expect false alarms or late detection)")
    try:
        model = tuple(float(g) for g in gains)
    except (TypeError, ValueError):
        return None
    if plant == "soft" and model != layer:
        return (f"{meta_path}: thresholds identified with damping gains {model}; the served layer damps "
                f"with {layer} (the link-2 contact is then detected late)")
    return None
