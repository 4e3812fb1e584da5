"""Command/state endpoint of the joint-control layer, with its safety shell.

:class:`JointLayerServer` receives datagrams from a :mod:`transport`, checks
them (:mod:`safety`), and drives a *core* - the object that actually moves
the arm - at a fixed control rate in wall time. The core is anything that
implements :class:`JointCore`; the simulated elastic TUDOR with its cascade,
damping and collision handling is wired in with :func:`register_core`.

Safety that the server owns, whatever the core:

* one owner at a time: a client opens a session (nonce handshake) and holds
  a lease, renewed by every valid datagram of the session and ended after
  ``lease_s`` of control time without one, on release, or on an explicit
  takeover (which stops the arm and goes IDLE); commands from anyone else
  are refused with ``NO_SESSION`` / ``NOT_OWNER`` and change nothing;
* with a key, every datagram must carry an HMAC-SHA256 tag (the long-term key
  outside a session, the session key inside); untagged, wrongly tagged,
  replayed (outside the session's sequence window) or forged-ahead datagrams
  are dropped and counted, never answered;
* velocity commands expire after ``watchdog_s`` of control time (default 0.1 s);
  then the velocity reference ramps to zero at the acceleration limits
  (controlled stop) and ``WATCHDOG_STOP`` is flagged;
* velocity references are speed-checked, acceleration-limited and braked so
  each joint stops inside its range; setpoints outside the ranges and profile
  limits outside sane bounds are refused (:class:`SafetyPolicy`);
* datagrams that fail to decode (checksum, length, NaN ...) are counted and
  never executed; well-formed but non-finite commands get a refusal;
* within a session, commands with an already seen sequence number
  (duplicates) or older than the newest one (stale, uint32 wrap-aware) are
  ignored; a duplicate of the last command gets its original reply again;
* a core state outside the joint ranges, above the speed limits or not
  finite, and any exception in the tick or the handler, stop the core and
  flag ``FAULT``; the layer keeps serving, and only the owner clears the
  fault with an explicit :class:`~tudorvision.joint.protocol.FaultReset`;
* in the wall-clock loop, sources other than the owner are rate-limited
  before decoding, and the owner's datagrams are handled first.

Examples
--------
>>> from tudorvision.joint.transport import InProcessTransport
>>> from tudorvision.joint.protocol import StateRequest, encode, decode
>>> client, end = InProcessTransport.pair()
>>> server = JointLayerServer(end, make_core("kinematic"))
>>> client.send(encode(StateRequest(), seq=1, t=0.0))
>>> server.run_for(0.05)
>>> decode(client.recv(1.0)[0])[1].mode.name
'IDLE'
"""
from __future__ import annotations

import collections
import ipaddress
import math
import os
import threading
import time
import types
from dataclasses import dataclass, field
from typing import Callable, Hashable, Protocol, runtime_checkable

import numpy as np

from .._checks import TudorVisionError, check_array
from . import protocol as P
from .safety import (SafetyLimits, SafetyPolicy, brake_velocity, check_setpoint,
                     check_velocity_command, ramp_velocity)

__all__ = ["CoreState", "JointCore", "KinematicCore", "ServerConfig", "CommandRecord", "ServerEvent",
           "JointLayerServer", "MAX_PAYLOAD_KG", "register_core", "make_core", "core_names"]


# ----------------------------------------------------------------- core interface
@dataclass(frozen=True, kw_only=True, eq=False)
class CoreState:
    """What a core reports after each step.

    Attributes
    ----------
    t : float
        Core time in s (advances by the ``dt`` given to :meth:`JointCore.step`).
    theta, theta_dot : ndarray, shape (3,)
        Joint angles (rad) and speeds (rad/s) at the gear output.
    strains : ndarray, shape (4,)
        Strain gauge signals in m/m (link 2 root, mid; link 3 root, mid).
    residuals : ndarray, shape (3,)
        Collision residuals per joint.
    collision : bool
        A collision is detected now.
    settled : bool
        The arm is at rest: the current setpoint is reached (or the stop is
        complete) and strains are inside the settling band.
    """

    t: float
    theta: np.ndarray
    theta_dot: np.ndarray
    strains: np.ndarray = field(default_factory=lambda: np.zeros(4))
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(3))
    collision: bool = False
    settled: bool = False


@runtime_checkable
class JointCore(Protocol):
    """The minimal interface between the server and the arm's joint controller.

    The server calls these from one thread only. Per control tick in velocity
    mode it calls :meth:`apply_velocity` then :meth:`step` while a command is
    live or the reference is still ramping down; once the reference is zero
    with no live command it calls :meth:`stop` once (position hold) and then
    only :meth:`step`. In the other modes it calls :meth:`step` each tick,
    :meth:`apply_setpoint` per accepted setpoint and :meth:`stop` on entering
    IDLE, on leaving VELOCITY and on a fault. All vectors are float64 arrays
    of shape (3,), SI units; ``state().t`` should advance by the stepped ``dt``.
    """

    def apply_velocity(self, theta_dot: np.ndarray) -> None:
        """Track this joint velocity reference (rad/s) from now on.

        The server has already checked, braked and acceleration-limited it.
        """

    def apply_setpoint(self, theta: np.ndarray, *, max_speed_rad_s: np.ndarray,
                       max_accel_rad_s2: np.ndarray) -> None:
        """Start a point-to-point motion to ``theta`` (rad) within these per-joint limits.

        May be called while the arm moves (a new setpoint replaces the old one).
        """

    def stop(self) -> None:
        """Controlled stop: decelerate within the acceleration limits and hold."""

    def set_modes(self, *, damping: P.Damping, collision: P.CollisionStrategy) -> None:
        """Select the damping law and the collision reaction strategy."""

    def step(self, dt: float) -> None:
        """Advance the arm by ``dt`` s (the core may sub-step, e.g. at 2 kHz)."""

    def state(self) -> CoreState:
        """Current state after the last :meth:`step`."""


class KinematicCore:
    """Rigid joint integrator: a stand-in core without elasticity.

    Velocity references are followed exactly; setpoints with a time-optimal
    bang-bang profile per joint; :meth:`stop` decelerates at the acceleration
    limit. Strains and residuals stay zero. Used by ``tudorvision joint serve
    --core kinematic`` until the simulated elastic arm is registered.

    Parameters
    ----------
    theta0 : array_like, shape (3,), optional
        Initial joint angles in rad (default: the vertical posture [0, 90°, 0]).
    limits : SafetyLimits, optional
        Acceleration limits for stops (default: the robot parameters).
    substep_s : float
        Integration step in s.

    Examples
    --------
    >>> core = KinematicCore(theta0=[0.0, 0.0, 0.0])
    >>> core.apply_velocity(np.array([0.1, 0.0, 0.0])); core.step(1.0)
    >>> round(float(core.state().theta[0]), 6)
    0.1
    """

    def __init__(self, theta0=None, *, limits: SafetyLimits | None = None,
                 substep_s: float = 1e-3):
        self._limits = limits or SafetyLimits.from_params()
        self._theta = (np.array([0.0, np.pi / 2, 0.0]) if theta0 is None
                       else check_array(theta0, "theta0", (3,)).copy())
        self._v = np.zeros(3)
        self._t = 0.0
        self._h = float(substep_s)
        self._mode = "stop"
        self._v_cmd = np.zeros(3)
        self._target = self._theta.copy()
        self._vmax = self._limits.max_speed_rad_s
        self._amax = self._limits.max_accel_rad_s2
        self.damping, self.collision = P.Damping.OFF, P.CollisionStrategy.NONE

    def apply_velocity(self, theta_dot):
        self._mode, self._v_cmd = "velocity", np.asarray(theta_dot, dtype=float).copy()

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2):
        self._mode, self._target = "setpoint", np.asarray(theta, dtype=float).copy()
        self._vmax = np.asarray(max_speed_rad_s, dtype=float)
        self._amax = np.asarray(max_accel_rad_s2, dtype=float)

    def stop(self):
        self._mode, self._amax = "stop", self._limits.max_accel_rad_s2

    def set_modes(self, *, damping, collision):
        self.damping, self.collision = P.Damping(damping), P.CollisionStrategy(collision)

    def set_payload(self, payload_kg: float) -> None:
        """Record the payload (a rigid integrator has no use for it)."""
        self.payload_kg = float(payload_kg)

    def step(self, dt):
        n = max(1, int(round(dt / self._h)))
        h = dt / n
        for _ in range(n):
            if self._mode == "velocity":
                self._v = self._v_cmd.copy()
            else:
                if self._mode == "setpoint":
                    e = self._target - self._theta
                    want = np.sign(e) * np.minimum.reduce(
                        [self._vmax, np.sqrt(2 * self._amax * np.abs(e)), np.abs(e) / h])
                else:
                    want = np.zeros(3)
                self._v = ramp_velocity(self._v, want, self._amax, h)
            self._theta = self._theta + self._v * h
            self._t += h

    def state(self) -> CoreState:
        at_rest = bool(np.all(np.abs(self._v) < 1e-6))
        reached = (self._mode != "setpoint"
                   or bool(np.all(np.abs(self._target - self._theta) < 1e-6)))
        return CoreState(t=self._t, theta=self._theta.copy(), theta_dot=self._v.copy(),
                         settled=at_rest and reached and self._mode != "velocity")


#: Largest payload a :class:`tudorvision.joint.protocol.PayloadUpdate` may announce, kg.
MAX_PAYLOAD_KG = 5.0

_CORES: dict[str, Callable[..., JointCore]] = {}


def register_core(name: str, factory: Callable[..., JointCore]) -> None:
    """Make a core available to :func:`make_core` and ``tudorvision joint serve --core``."""
    _CORES[name] = factory


def core_names() -> list[str]:
    """Names accepted by :func:`make_core`."""
    return sorted(_CORES)


def make_core(name: str, **options) -> JointCore:
    """Build a registered core by name: ``"kinematic"`` or ``"sim"`` (the elastic arm).

    Raises
    ------
    TudorVisionError
        If no core of that name is registered.
    """
    try:
        factory = _CORES[name]
    except KeyError:
        raise TudorVisionError(f"core: unknown core {name!r}; available: "
                               f"{', '.join(core_names())}") from None
    return factory(**options)


register_core("kinematic", KinematicCore)

# StateFlags bits as plain ints: IntFlag arithmetic costs microseconds per operation.
_F = types.SimpleNamespace(**{f.name: int(f) for f in P.StateFlags})


# ------------------------------------------------------------------------ server
@dataclass(frozen=True, kw_only=True)
class ServerConfig:
    """Options of :class:`JointLayerServer`.

    Attributes
    ----------
    rate_hz : float
        Control rate of the server loop (the core may sub-step faster).
    watchdog_s : float
        Lifetime of a velocity command in control time (the sum of the steps
        given to the core: wall time unless the loop falls behind).
    max_command_age_s : float or None
        Motion commands that arrive later than this relative to the fastest
        delivery seen from their sender are ignored as stale (None: off).
    initial_mode : Mode
    policy : SafetyPolicy
    rest_speed_rad_s : float
        Joint speed below which the arm is not ``MOVING``.
    fault_speed_factor, fault_range_tol_rad : float
        A core state faster than factor x speed limit is a fault; so is a
        joint that goes further than the tolerance outside its range, or is
        outside and moving further out (outside and at rest or moving back,
        it may be brought back after the fault is reset).
    fault_accel_factor : float or None
        With a number, a joint speed change faster than this times the
        acceleration limit (over ``accel_window_s``) is a fault too; off by
        default because an elastic arm's measured joint speed may ring above
        the commanded acceleration.
    accel_window_s : float
        Window of that acceleration estimate.
    max_clients, seq_window, log_size, max_backlog_ticks : int
        Bounds of the per-client tables, the duplicate window, the command log
        and of catch-up ticks after a stall (beyond it ticks are skipped and
        counted as overruns).
    lease_s : float
        The owner's lease in control time: it ends after this long without a
        valid datagram of its session.
    allow_takeover : bool
        Let a client open a session with ``takeover`` while another holds the
        lease (the layer stops the arm and goes IDLE first).
    seq_ahead : int
        Largest jump of the sequence number within a session; a datagram
        further ahead is dropped as forged and never moves the window.
    source_rate_hz, source_burst : float
        Token bucket per source address other than the owner's, applied
        before decoding (wall-clock loop only).
    max_sources : int
        Bound of the rate limiter's table of sources.
    handshake_timeout_s : float
        A challenge not answered within this wall time is forgotten.
    max_batch : int
        Datagrams read per burst before the owner's are handled first.
    """

    rate_hz: float = 500.0
    watchdog_s: float = 0.1
    max_command_age_s: float | None = 0.25
    initial_mode: P.Mode = P.Mode.IDLE
    policy: SafetyPolicy = SafetyPolicy()
    rest_speed_rad_s: float = 1e-3
    fault_speed_factor: float = 1.05
    fault_range_tol_rad: float = np.deg2rad(1.0)
    fault_accel_factor: float | None = None
    accel_window_s: float = 0.02
    max_clients: int = 64
    seq_window: int = 256
    log_size: int = 4096
    max_backlog_ticks: int = 10
    lease_s: float = 1.0
    allow_takeover: bool = True
    seq_ahead: int = 4096
    source_rate_hz: float = 1000.0
    source_burst: float = 200.0
    max_sources: int = 1024
    handshake_timeout_s: float = 2.0
    max_batch: int = 64

    def __post_init__(self):
        for name in ("rate_hz", "watchdog_s", "lease_s", "source_rate_hz", "source_burst",
                     "handshake_timeout_s", "accel_window_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be positive and finite, got {v}")
        if self.fault_accel_factor is not None and not self.fault_accel_factor >= 1.0:
            raise ValueError(f"fault_accel_factor: expected None or >= 1, got {self.fault_accel_factor}")
        for name in ("max_clients", "seq_window", "log_size", "seq_ahead", "max_sources", "max_batch"):
            if not int(getattr(self, name)) >= 1:
                raise ValueError(f"{name}: must be >= 1, got {getattr(self, name)}")


@dataclass(frozen=True)
class CommandRecord:
    """One handled command: times, sender, sequence number, message, outcome code and session."""

    t_wall: float
    t_core: float
    client: Hashable
    seq: int
    msg: object
    code: P.Reason
    session: int = 0


@dataclass(frozen=True)
class ServerEvent:
    """Something the layer did on its own: ``kind`` is one of ``session_open``,
    ``session_end``, ``takeover``, ``fault``, ``fault_reset``, ``watchdog_stop``."""

    t_wall: float
    t_core: float
    kind: str
    text: str = ""


_DRIFT = 1e-3   # tolerated clock drift between sender and layer, s/s (1000 ppm)


class _Client:
    """Sequence-number bookkeeping for one session."""

    __slots__ = ("newest", "window", "seen", "last_reply", "floor", "floor_t")

    def __init__(self):
        self.newest = None
        self.window = collections.deque()
        self.seen = set()
        self.last_reply = None     # (seq, datagram)
        self.floor = None          # lowest (receive - send) time seen, drifting up slowly
        self.floor_t = 0.0

    def age(self, t_recv: float, t_sent: float) -> float:
        """Delay of this datagram beyond the fastest delivery seen from this sender.

        The sender's clock is unrelated to ours; only differences matter. The
        floor rises by ``_DRIFT`` s per s so clock drift between two PCs never
        makes fresh commands look old.
        """
        delay = t_recv - t_sent
        if self.floor is None or delay < self.floor + _DRIFT * (t_recv - self.floor_t):
            self.floor, self.floor_t = delay, t_recv
        return delay - self.floor - _DRIFT * (t_recv - self.floor_t)

    def classify(self, seq: int, window: int, ahead: int = 2**31 - 1) -> str:
        """Return "new", "duplicate", "stale" (older, inside the window), or
        "replayed" (older than the window, or more than ``ahead`` newer); record ``seq`` if new."""
        if seq in self.seen:
            return "duplicate"
        if self.newest is not None:
            d = (seq - self.newest) & 0xFFFFFFFF
            if d == 0 or d >= 0x80000000:
                return "stale" if (self.newest - seq) & 0xFFFFFFFF < window else "replayed"
            if d > ahead:
                return "replayed"
        self.newest = seq
        self.window.append(seq)
        self.seen.add(seq)
        while len(self.window) > window:
            self.seen.discard(self.window.popleft())
        return "new"


class _Session:
    """The owner's session: id, address, key, sequence window and lease."""

    __slots__ = ("sid", "addr", "key", "client", "last_seen", "server_nonce", "welcome", "end_reason")

    def __init__(self, sid, addr, key, server_nonce, welcome, t_ctrl):
        self.sid, self.addr, self.key = sid, addr, key
        self.client = _Client()
        self.last_seen = t_ctrl
        self.server_nonce = server_nonce
        self.welcome = welcome            # the Welcome datagram, resent for a retransmitted Open
        self.end_reason = ""


class _RateLimiter:
    """Token bucket per source address, bounded table (oldest sources forgotten)."""

    def __init__(self, rate_hz: float, burst: float, max_sources: int):
        self.rate, self.burst, self.max = float(rate_hz), float(burst), int(max_sources)
        self._buckets: collections.OrderedDict = collections.OrderedDict()

    def allow(self, addr, now: float) -> bool:
        b = self._buckets.get(addr)
        if b is None:
            if len(self._buckets) >= self.max:
                self._buckets.popitem(last=False)
            self._buckets[addr] = [self.burst - 1.0, now]
            return True
        tokens = min(self.burst, b[0] + (now - b[1]) * self.rate)
        b[1] = now
        if tokens < 1.0:
            b[0] = tokens
            return False
        b[0] = tokens - 1.0
        return True


def _is_loopback(addr) -> bool:
    """True for in-process addresses and IP addresses on loopback."""
    if not isinstance(addr, tuple):
        return True
    try:
        return ipaddress.ip_address(addr[0]).is_loopback
    except ValueError:
        return addr[0] == "localhost"


class JointLayerServer:
    """The joint-control layer's endpoint: transport in, core out, safety between.

    Parameters
    ----------
    transport : Transport
        Bound server end (:class:`~tudorvision.joint.transport.UdpTransport` or
        the server end of an in-process pair).
    core : JointCore
        The object that moves the arm.
    limits : SafetyLimits, optional
        Default: from the robot parameters.
    config : ServerConfig, optional
    key : bytes, optional
        Long-term key (:func:`~tudorvision.joint.protocol.read_key_file`).
        With it every datagram must carry a valid HMAC-SHA256 tag; without it
        the transport must be bound on loopback (or in-process).

    Raises
    ------
    TudorVisionError
        If the transport is bound to a non-loopback address without a key.

    Notes
    -----
    Run it with :meth:`serve_forever` (blocking, until :meth:`shutdown`),
    :meth:`run_for` (blocking, bounded) or :meth:`start` / as a context manager
    (background thread, stopped and joined on exit). Only the loop thread
    touches the core; :meth:`state`, :attr:`counters`, :meth:`command_log`
    and :meth:`events` are safe to call from other threads.
    """

    def __init__(self, transport, core: JointCore, *, limits: SafetyLimits | None = None,
                 config: ServerConfig = ServerConfig(), key: bytes | None = None):
        if not isinstance(core, JointCore):
            raise TypeError(f"core: {type(core).__name__} does not implement JointCore")
        bound = getattr(transport, "address", None)
        if key is None and not _is_loopback(bound):
            raise TudorVisionError(f"transport: bound on {bound[0]}, not loopback; a key is required "
                                   f"to serve beyond this machine (tudorvision joint keygen)")
        self.transport = transport
        self.core = core
        self.limits = limits or SafetyLimits.from_params()
        self.config = config
        self._key = None if key is None else bytes(key)
        if self._key is not None and len(self._key) < 16:
            raise ValueError(f"key: expected at least 16 bytes, got {len(self._key)}")
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread = None
        self._log = collections.deque(maxlen=config.log_size)
        self._events = collections.deque(maxlen=config.log_size)
        self._counts = dict.fromkeys(P.Counters.__dataclass_fields__, 0)
        self._seq = 0
        self._mode = P.Mode(config.initial_mode)
        self._damping, self._collision = P.Damping.OFF, P.CollisionStrategy.NONE
        self._flags = 0
        self._last_command_seq = 0
        self._v_target = np.zeros(3)
        self._v_ref = np.zeros(3)
        self._deadline = -np.inf
        self._t_ctrl = 0.0          # control time: sum of the dt given to the core
        self._armed = False
        self._holding = False       # velocity mode at rest: the core holds position via stop()
        self._outside = np.zeros(3, dtype=bool)   # joints beyond range + tolerance at the last tick
        self._period = 1.0 / config.rate_hz
        self._owner: _Session | None = None
        self._ended: collections.OrderedDict = collections.OrderedDict()   # sid -> ended _Session
        self._challenges: collections.OrderedDict = collections.OrderedDict()  # server nonce -> ...
        self._limiter = _RateLimiter(config.source_rate_hz, config.source_burst, config.max_sources)
        self._ticks = collections.deque()           # (t_wall, interval) over the last second
        self._last_tick_wall = None
        self._tick_stats, self._tick_stats_at = (0.0, 0.0, 0.0), None
        self._speeds = collections.deque()          # (t_core, theta_dot) for the acceleration check
        core.set_modes(damping=self._damping, collision=self._collision)
        core.stop()
        self._core_state = core.state()

    # ------------------------------------------------------------ public view
    @property
    def address(self):
        """Address of the transport (``(host, port)`` for UDP)."""
        return self.transport.address

    @property
    def authenticated(self) -> bool:
        """True when the layer has a key (every datagram must carry a valid tag)."""
        return self._key is not None

    @property
    def counters(self) -> P.Counters:
        """Snapshot of the event counters."""
        with self._lock:
            return P.Counters(**self._counts)

    @property
    def mode(self) -> P.Mode:
        return self._mode

    @property
    def owner(self):
        """``(session id, address)`` of the lease holder, or ``None``."""
        with self._lock:
            o = self._owner
            return None if o is None else (o.sid, o.addr)

    def command_log(self) -> list[CommandRecord]:
        """The most recent handled commands (bounded by ``config.log_size``)."""
        with self._lock:
            return list(self._log)

    def events(self) -> list[ServerEvent]:
        """The most recent events (sessions, faults, watchdog stops; bounded by ``config.log_size``)."""
        with self._lock:
            return list(self._events)

    def tick_stats(self) -> tuple[float, float, float]:
        """Tick-interval p50, p99 and maximum in s over the last second of the wall-clock loop.

        Recomputed at most every 50 ms (a State request must stay cheap).
        """
        with self._lock:
            now = time.monotonic()
            if self._tick_stats_at is not None and now - self._tick_stats_at < 0.05:
                return self._tick_stats
            iv = sorted(x for _, x in self._ticks)
            if iv:
                n = len(iv)
                self._tick_stats = (iv[(n - 1) // 2], iv[min(n - 1, int(0.99 * (n - 1) + 0.5))], iv[-1])
            else:
                self._tick_stats = (0.0, 0.0, 0.0)
            self._tick_stats_at = now
            return self._tick_stats

    def state(self, request_seq: int = 0) -> P.State:
        """The state feedback message for the current core state."""
        p50, p99, worst = self.tick_stats()
        with self._lock:
            cs = self._core_state
            flags = self._flags & ~(_F.SETTLED | _F.MOVING | _F.COLLISION | _F.OWNED)
            if cs.settled:
                flags |= _F.SETTLED
            if np.any(np.abs(cs.theta_dot) > self.config.rest_speed_rad_s):
                flags |= _F.MOVING
            if cs.collision:
                flags |= _F.COLLISION
            if self._owner is not None:
                flags |= _F.OWNED
            return P.State(t=cs.t, theta=cs.theta, theta_dot=cs.theta_dot, strains=cs.strains,
                           residuals=cs.residuals, flags=flags, mode=self._mode,
                           damping=self._damping, collision=self._collision,
                           last_command_seq=self._last_command_seq, request_seq=request_seq,
                           counters=P.Counters(**self._counts),
                           tick_p50_s=p50, tick_p99_s=p99, tick_max_s=worst)

    # ------------------------------------------------------- lockstep driving
    def poll(self) -> int:
        """Handle every message already waiting on the transport, without blocking.

        For simulations that drive the layer in simulated time instead of a
        wall-clock thread (see :meth:`tick`). Returns the number handled.
        No rate limit applies here (the simulation owns the clock).
        """
        handled = 0
        item = self.transport.recv(0.0)
        while item is not None:
            self._handle_safe(*item)
            handled += 1
            item = self.transport.recv(0.0)
        return handled

    def tick(self, dt: float) -> None:
        """Handle waiting messages, then run one control period of ``dt`` seconds.

        The lockstep alternative to :meth:`serve_forever`: the caller owns the
        clock (a simulation advancing the plant in simulated time). Do not mix
        with a running background loop.
        """
        if not dt > 0:
            raise ValueError(f"dt: must be positive, got {dt}")
        self.poll()
        self._tick(float(dt))

    # ------------------------------------------------------------- lifecycle
    def serve_forever(self, rate_hz: float | None = None) -> None:
        """Run the control loop until :meth:`shutdown` is called (from another thread)."""
        self._stop.clear()
        self._loop(rate_hz, None)

    def run_for(self, seconds: float, rate_hz: float | None = None) -> None:
        """Run the control loop in the calling thread for ``seconds`` of wall time."""
        self._stop.clear()
        self._loop(rate_hz, float(seconds))

    def start(self, rate_hz: float | None = None) -> "JointLayerServer":
        """Run :meth:`serve_forever` in a daemon thread; returns self."""
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("server already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, args=(rate_hz, None),
                                        name="joint-layer-server", daemon=True)
        self._thread.start()
        return self

    def shutdown(self, timeout: float = 2.0) -> None:
        """Stop the loop and join the background thread (if any)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            if self._thread.is_alive():
                raise RuntimeError("server thread did not stop within the timeout")
            self._thread = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.shutdown()

    # ------------------------------------------------------------------ loop
    def _loop(self, rate_hz, duration):
        if rate_hz is not None:
            if not rate_hz > 0:
                raise ValueError(f"rate_hz: must be positive, got {rate_hz}")
            self._period = 1.0 / rate_hz
        period = self._period
        now = time.monotonic()
        end = None if duration is None else now + duration
        next_tick = now + period
        self._last_tick_wall = None
        while not self._stop.is_set():
            now = time.monotonic()
            if end is not None and now >= end:
                break
            if now >= next_tick:
                behind = int((now - next_tick) / period)
                if behind > self.config.max_backlog_ticks:
                    next_tick += behind * period
                    with self._lock:
                        self._count(overruns=behind)
                self._record_tick(now)
                self._tick(period)
                next_tick += period
                continue
            wait = next_tick - now
            if end is not None:
                wait = min(wait, max(end - now, 0.0))
            try:
                item = self.transport.recv(wait)
            except OSError:
                if self._stop.is_set():
                    break
                raise
            if item is not None:
                self._handle_batch(item, next_tick)

    def _handle_batch(self, first, next_tick: float) -> None:
        """Read up to ``max_batch`` datagrams, drop rate-limited strangers, handle the owner's first."""
        owner_items, others = [], []
        limiter, now = self._limiter, time.monotonic()
        item = first
        while item is not None:
            owner = self._owner
            if owner is not None and item[1] == owner.addr:
                owner_items.append(item)
            elif limiter.allow(item[1], now):
                others.append(item)
            else:
                self._counts["rate_limited"] += 1
            if len(owner_items) + len(others) >= self.config.max_batch or time.monotonic() >= next_tick:
                break
            try:
                item = self.transport.recv(0.0)
            except OSError:
                break
        for item in owner_items:
            self._handle_safe(*item)
        for item in others:
            self._handle_safe(*item)

    def _record_tick(self, now: float) -> None:
        last, self._last_tick_wall = self._last_tick_wall, now
        if last is None:
            return
        with self._lock:
            self._ticks.append((now, now - last))
            while self._ticks and self._ticks[0][0] < now - 1.0:
                self._ticks.popleft()

    def _count(self, **inc):
        for k, v in inc.items():
            self._counts[k] += v

    def _event(self, kind: str, text: str = "") -> None:
        self._events.append(ServerEvent(time.monotonic(), float(self._core_state.t), kind, text))

    def _fault(self, text: str) -> None:
        """Stop the core (if it still can), go IDLE and flag FAULT; never raises."""
        first = not self._flags & _F.FAULT
        self._flags |= _F.FAULT
        if first:
            self._count(faults=1)
            self._event("fault", text)
        try:
            self._enter_mode(P.Mode.IDLE)
        except Exception:            # a core that cannot even stop: keep serving, stay in FAULT
            self._mode = P.Mode.IDLE
            self._v_ref = np.zeros(3)
            self._v_target = np.zeros(3)
            self._armed = False

    def _tick(self, dt: float) -> None:
        with self._lock:
            try:
                self._tick_core(dt)
            except Exception as exc:       # noqa: BLE001 - the shell faults, never crashes
                self._fault(f"exception in the control tick: {type(exc).__name__}: {exc}")
            owner = self._owner
            if owner is not None and self._t_ctrl - owner.last_seen > self.config.lease_s:
                self._end_session(f"lease expired ({self.config.lease_s:g} s without a datagram)")

    def _tick_core(self, dt: float) -> None:
        cs = self._core_state
        if self._mode == P.Mode.VELOCITY:
            if self._armed and self._t_ctrl >= self._deadline:
                self._armed = False
                self._v_target = np.zeros(3)
                self._flags |= _F.WATCHDOG_STOP
                self._count(watchdog_stops=1)
                self._event("watchdog_stop", f"no velocity command for {self.config.watchdog_s:g} s")
            braked = brake_velocity(cs.theta, self._v_target, self.limits, dt,
                                    theta_dot_now=self._v_ref)
            if np.array_equal(braked, self._v_target):
                self._flags &= ~_F.LIMIT_BRAKE
            else:
                self._flags |= _F.LIMIT_BRAKE
            v_ref = ramp_velocity(self._v_ref, braked, self.limits.max_accel_rad_s2, dt)
            if not np.all(np.isfinite(v_ref)):
                raise FloatingPointError(f"velocity reference {v_ref.tolist()} is not finite")
            self._v_ref = v_ref
            if not self._armed and not np.any(self._v_ref):
                if not self._holding:      # at rest without a live command: hold position
                    self.core.stop()
                    self._holding = True
            else:
                self._holding = False
                self.core.apply_velocity(self._v_ref.copy())
        self.core.step(dt)
        self._t_ctrl += dt
        new = self.core.state()
        if not all(np.all(np.isfinite(np.asarray(x, dtype=float)))
                   for x in (new.t, new.theta, new.theta_dot, new.strains, new.residuals)):
            self._fault("core state holds NaN or infinite values")   # keep the last finite state
            return
        self._core_state = cs = new
        over_speed = np.any(np.abs(cs.theta_dot)
                            > self.config.fault_speed_factor * self.limits.max_speed_rad_s)
        out = self._range_fault(cs)
        over_accel = self._accel_fault(cs)
        if (over_speed or out or over_accel) and not self._flags & _F.FAULT:
            what = "speed" if over_speed else "range" if out else "acceleration"
            self._fault(f"core state outside the {what} limits")

    def _accel_fault(self, cs) -> bool:
        factor = self.config.fault_accel_factor
        if factor is None:
            return False
        w = self._speeds
        w.append((float(cs.t), np.asarray(cs.theta_dot, dtype=float)))
        while len(w) > 2 and w[1][0] <= cs.t - self.config.accel_window_s:
            w.popleft()
        span = w[-1][0] - w[0][0]
        if span < 0.5 * self.config.accel_window_s:
            return False
        accel = np.abs(w[-1][1] - w[0][1]) / span
        return bool(np.any(accel > factor * self.limits.max_accel_rad_s2))

    def _range_fault(self, cs) -> bool:
        """A joint left its range (beyond the tolerance) on this tick, or is outside and moving further out.

        A joint that is already outside and at rest or moving back does not
        fault again, so a reset fault sticks and a setpoint can bring the
        arm back into its range.
        """
        lim, tol = self.limits.joint_limits_rad, self.config.fault_range_tol_rad
        below, above = cs.theta < lim[:, 0] - tol, cs.theta > lim[:, 1] + tol
        v, rest = np.asarray(cs.theta_dot), self.config.rest_speed_rad_s
        outward = (below & (v < -rest)) | (above & (v > rest))
        entered = (below | above) & ~self._outside
        self._outside = below | above
        return bool(np.any(entered) or np.any(outward))

    def _enter_mode(self, mode: P.Mode) -> None:
        if mode == P.Mode.VELOCITY:
            if self._mode != P.Mode.VELOCITY:
                self._v_ref = np.asarray(self._core_state.theta_dot, dtype=float).copy()
                self._v_target = np.zeros(3)   # ramps down from the current speed
                self._armed = False
                self._holding = False
        elif self._mode == P.Mode.VELOCITY or mode == P.Mode.IDLE:
            self.core.stop()
            self._v_ref = np.zeros(3)
            self._v_target = np.zeros(3)
            self._armed = False
        self._mode = mode

    # --------------------------------------------------------------- sessions
    def _end_session(self, reason: str) -> None:
        o = self._owner
        if o is None:
            return
        o.end_reason = reason
        self._owner = None
        self._ended[o.sid] = o
        while len(self._ended) > 16:
            self._ended.popitem(last=False)
        self._event("session_end", f"session {o.sid:#010x}: {reason}")

    def _new_sid(self) -> int:
        while True:
            sid = int.from_bytes(os.urandom(4), "big")
            if sid and sid not in self._ended:
                return sid

    def _handshake(self, header, msg, addr) -> None:
        cfg, now = self.config, time.monotonic()
        if self._key is None and not _is_loopback(addr):
            self._count(unauthenticated=1)
            return
        while self._challenges and next(iter(self._challenges.values()))[2] < now - cfg.handshake_timeout_s:
            self._challenges.popitem(last=False)
        if isinstance(msg, P.Hello):
            nonce = P.new_nonce()
            self._challenges[nonce] = (addr, msg.client_nonce, now)
            while len(self._challenges) > cfg.max_clients:
                self._challenges.popitem(last=False)
            self._send(P.Challenge(client_nonce=msg.client_nonce, server_nonce=nonce), addr, key=self._key)
            return
        if not isinstance(msg, P.OpenSession):
            self._count(malformed=1)      # Challenge/Welcome sent to the layer: protocol misuse
            return
        o = self._owner
        if o is not None and o.server_nonce == msg.server_nonce and o.addr == addr:
            self._transmit(o.welcome, addr)     # the Welcome was lost: same answer again
            return
        pending = self._challenges.pop(msg.server_nonce, None)
        if pending is None or pending[0] != addr or pending[1] != msg.client_nonce:
            self._count(replayed=1)             # unknown, used or expired challenge: a replay
            return
        if o is not None and o.addr != addr:
            if not (msg.takeover and cfg.allow_takeover):
                self._count(not_owner=1)
                left = max(cfg.lease_s - (self._t_ctrl - o.last_seen), 0.0)
                self._send(P.Refusal(command_seq=header.seq, code=P.Reason.NOT_OWNER,
                                     text=f"another client holds the lease (expires after {left:.2f} s "
                                          f"of silence); open with takeover to take it"),
                           addr, key=self._key)
                return
            self._end_session(f"taken over by {addr}")
            self._event("takeover", f"by {addr}: arm stopped, mode IDLE")
            self._enter_mode(P.Mode.IDLE)
        elif o is not None:
            self._end_session("reopened by the same client")
        sid = self._new_sid()
        skey = P.session_key(self._key, msg.client_nonce, msg.server_nonce, sid)
        welcome = P.Welcome(client_nonce=msg.client_nonce, session=sid, lease_s=cfg.lease_s)
        self._seq = P.seq_add(self._seq)
        data = P.encode(welcome, self._seq, time.monotonic(), key=self._key)
        self._owner = _Session(sid, addr, skey, msg.server_nonce, data, self._t_ctrl)
        self._event("session_open", f"session {sid:#010x} for {addr}")
        self._transmit(data, addr)

    # --------------------------------------------------------------- packets
    def _transmit(self, data: bytes, addr) -> None:
        try:
            self.transport.send(data, addr)
        except OSError:
            pass    # datagram semantics: a failed reply is a lost reply

    def _send(self, msg, addr, *, key=None, session: int = 0) -> bytes:
        self._seq = P.seq_add(self._seq)
        data = P.encode(msg, self._seq, time.monotonic(), session=session, key=key)
        self._transmit(data, addr)
        return data

    def _handle_safe(self, data: bytes, addr) -> None:
        try:
            self._handle(data, addr)
        except Exception as exc:     # noqa: BLE001 - the shell faults, never crashes
            with self._lock:
                self._fault(f"exception while handling a datagram: {type(exc).__name__}: {exc}")

    def _handle(self, data: bytes, addr) -> None:
        t_recv = time.monotonic()
        with self._lock:
            try:
                sid, _, _ = P.peek(data)
            except P.ProtocolError:
                self._count(malformed=1)
                return
            owner = self._owner
            if sid == 0:
                session, key = None, self._key
            elif owner is not None and sid == owner.sid:
                session, key = owner, owner.key
            elif sid in self._ended:
                session = self._ended[sid]
                key = session.key
            elif self._key is not None:
                self._count(unauthenticated=1)    # no key known for it: cannot be checked
                return
            else:
                session, key = None, None
            try:
                header, msg = P.decode(data, key=key)
            except P.Unauthenticated:
                self._count(unauthenticated=1)
                return
            except P.ProtocolError as err:
                self._count(malformed=1)
                h = err.header
                if (h is not None and session is owner and owner is not None and addr == owner.addr
                        and h.msg_type in (P.MsgType.VELOCITY, P.MsgType.SETPOINT,
                                           P.MsgType.MODE, P.MsgType.PAYLOAD)
                        and owner.client.classify(h.seq, self.config.seq_window,
                                                  self.config.seq_ahead) == "new"):
                    owner.last_seen = self._t_ctrl
                    self._flags |= _F.REFUSED
                    self._send(P.Refusal(command_seq=h.seq, code=err.reason, text=str(err)), addr,
                               key=owner.key, session=owner.sid)
                return
            if sid == 0:
                if isinstance(msg, P.StateRequest):
                    self._send(self.state(request_seq=header.seq), addr, key=self._key)
                elif isinstance(msg, P.SESSION_TYPES):
                    self._handshake(header, msg, addr)
                elif isinstance(msg, P.COMMAND_TYPES):
                    self._count(not_owner=1)
                    self._send(P.Refusal(command_seq=header.seq, code=P.Reason.NO_SESSION,
                                         text="no session: open one (Hello) before sending commands"),
                               addr, key=self._key)
                else:
                    self._count(malformed=1)
                return
            if session is None or session.addr != addr or session is not owner:
                self._count(not_owner=1)
                if session is not None and session.addr == addr:      # an ended session of this client
                    text = f"session ended: {session.end_reason}"
                    code = P.Reason.NO_SESSION
                else:
                    text, code = "not the session owner", P.Reason.NOT_OWNER
                if isinstance(msg, (P.StateRequest, *P.COMMAND_TYPES)):
                    self._send(P.Refusal(command_seq=header.seq, code=code, text=text), addr,
                               key=key, session=sid)
                return
            client = owner.client
            verdict = client.classify(header.seq, self.config.seq_window, self.config.seq_ahead)
            if verdict == "replayed":
                self._count(replayed=1)
                return
            owner.last_seen = self._t_ctrl
            if isinstance(msg, P.StateRequest):
                self._send(self.state(request_seq=header.seq), addr, key=key, session=sid)
                return
            if not isinstance(msg, P.COMMAND_TYPES):
                self._count(malformed=1)     # replies sent to the server: protocol misuse
                return
            if verdict == "duplicate":
                self._count(duplicates=1)
                if client.last_reply is not None and client.last_reply[0] == header.seq:
                    self._transmit(client.last_reply[1], addr)
                return
            if verdict == "stale":
                self._count(stale=1)
                return
            age = client.age(t_recv, header.t_sent)
            max_age = self.config.max_command_age_s
            if (max_age is not None and age > max_age
                    and isinstance(msg, (P.JointVelocityCommand, P.JointSetpoint))):
                self._count(stale=1)
                reply = P.Refusal(command_seq=header.seq, code=P.Reason.STALE,
                                  text=f"command arrived {age * 1e3:.0f} ms late")
            else:
                try:
                    reply = self._execute(msg, header.seq)
                except Exception as exc:     # noqa: BLE001 - the shell faults, never crashes
                    self._fault(f"exception executing {type(msg).__name__}: {type(exc).__name__}: {exc}")
                    reply = self._refuse(header.seq, P.Reason.INTERNAL,
                                         f"internal error ({type(exc).__name__}); core stopped, FAULT")
            self._log.append(CommandRecord(t_wall=t_recv, t_core=self._core_state.t, client=addr,
                                           seq=header.seq, msg=msg, code=reply.code, session=sid))
            client.last_reply = (header.seq, self._send(reply, addr, key=key, session=sid))
            if isinstance(msg, P.Release) and isinstance(reply, P.Ack):
                self._end_session("released by its owner")

    def _refuse(self, seq: int, code: P.Reason, text: str) -> P.Refusal:
        self._count(refused=1)
        self._flags = (self._flags | _F.REFUSED) & ~_F.CLAMPED
        return P.Refusal(command_seq=seq, code=code, text=text)

    def _accept(self, seq: int, code: P.Reason, text: str) -> P.Ack:
        self._count(accepted=1)
        self._last_command_seq = seq
        self._flags &= ~(_F.REFUSED | _F.CLAMPED)
        if code != P.Reason.OK:
            self._flags |= _F.CLAMPED
        return P.Ack(command_seq=seq, code=code, text=text)

    def _execute(self, msg, seq: int):
        if isinstance(msg, P.Release):
            return self._accept(seq, P.Reason.OK, "session released")
        if isinstance(msg, P.FaultReset):
            if self._flags & _F.FAULT:
                self._flags &= ~(_F.FAULT | _F.WATCHDOG_STOP)
                self._event("fault_reset", "by the session owner")
            return self._accept(seq, P.Reason.OK, "")
        if isinstance(msg, P.ModeSwitch):
            damping = self._damping if msg.damping is None else msg.damping
            collision = self._collision if msg.collision is None else msg.collision
            if (damping, collision) != (self._damping, self._collision):
                self.core.set_modes(damping=damping, collision=collision)
                self._damping, self._collision = damping, collision
            if msg.mode is not None:
                self._enter_mode(msg.mode)
            self._flags &= ~_F.WATCHDOG_STOP        # a mode switch never clears FAULT
            return self._accept(seq, P.Reason.OK, "fault stop still set: send a fault reset"
                                if self._flags & _F.FAULT else "")
        if isinstance(msg, P.PayloadUpdate):
            m = msg.payload_kg
            if not 0.0 <= m <= MAX_PAYLOAD_KG:
                return self._refuse(seq, P.Reason.OUT_OF_RANGE,
                                    f"payload_kg {m:g} outside [0, {MAX_PAYLOAD_KG:g}] kg")
            set_payload = getattr(self.core, "set_payload", None)
            if set_payload is None:
                return self._refuse(seq, P.Reason.UNSUPPORTED,
                                    f"core {type(self.core).__name__} has no payload model")
            set_payload(m)
            return self._accept(seq, P.Reason.OK, "")
        if self._flags & _F.FAULT:
            return self._refuse(seq, P.Reason.FAULT, "fault stop; the owner must send a fault reset")
        want = P.Mode.VELOCITY if isinstance(msg, P.JointVelocityCommand) else P.Mode.SETPOINT
        if self._mode != want:
            return self._refuse(seq, P.Reason.WRONG_MODE,
                                f"{type(msg).__name__} needs mode {want.name}, "
                                f"layer is in {self._mode.name}")
        if isinstance(msg, P.JointVelocityCommand):
            v = check_velocity_command(msg.theta_dot, self.limits, policy=self.config.policy)
            if not v.accepted:
                return self._refuse(seq, v.code, v.text)
            self._v_target = v.value
            self._deadline = self._t_ctrl + self.config.watchdog_s
            self._armed = True
            self._flags &= ~_F.WATCHDOG_STOP
            return self._accept(seq, v.code, v.text)
        s = check_setpoint(msg.theta, self.limits, max_speed=msg.max_speed,
                           max_accel=msg.max_accel, policy=self.config.policy)
        if not s.accepted:
            return self._refuse(seq, s.code, s.text)
        self.core.apply_setpoint(s.value, max_speed_rad_s=s.max_speed_rad_s,
                                 max_accel_rad_s2=s.max_accel_rad_s2)
        return self._accept(seq, s.code, s.text)
