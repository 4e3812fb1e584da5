"""Command/state endpoint of the joint-control layer, with its safety shell.

:class:`JointLayerServer` receives datagrams from a :mod:`transport`, checks
them (:mod:`safety`), and drives a *core* - the object that actually moves
the arm - at a fixed control rate in wall time: any :class:`~.cores.JointCore`
(:mod:`cores`, with the :func:`register_core` registry). Its state lives in
small pieces: :mod:`session` (lease, replay window, challenges, rate limit),
:mod:`velocity_ref` (watchdog and ramp), :mod:`state_faults`, :mod:`tick_stats`,
:mod:`server_loop` (the wall-clock loop) and :mod:`server_config`.

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
import threading
import time
import types

import numpy as np

from .._checks import TudorVisionError
from . import protocol as P
from .cores import (MAX_PAYLOAD_KG, CoreState, JointCore, KinematicCore, PayloadAwareCore, core_names, make_core,
                    register_core)
from .safety import SafetyLimits, check_setpoint, check_velocity_command
from .server_config import CommandRecord, ServerConfig, ServerEvent
from .server_loop import WallClockLoop
from .session import RateLimiter, Session, SessionTable, is_loopback
from .state_faults import StateFaultMonitor
from .tick_stats import TickStats
from .velocity_ref import VelocityReference

__all__ = ["CoreState", "JointCore", "PayloadAwareCore", "KinematicCore", "ServerConfig", "CommandRecord",
           "ServerEvent", "JointLayerServer", "MAX_PAYLOAD_KG", "register_core", "make_core", "core_names"]


# StateFlags bits as plain ints: IntFlag arithmetic costs microseconds per operation.
_F = types.SimpleNamespace(**{f.name: int(f) for f in P.StateFlags})


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
        if key is None and not is_loopback(bound):
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
        self._vel = VelocityReference(config.watchdog_s)
        self._t_ctrl = 0.0          # control time: sum of the dt given to the core
        self._period = 1.0 / config.rate_hz
        self._sessions = SessionTable(max_challenges=config.max_clients,
                                      handshake_timeout_s=config.handshake_timeout_s)
        self._wall = WallClockLoop(transport, tick=self._tick, handle=self._handle_safe, owner_addr=self._sessions.owner_addr,
                                   record_tick=self._record_tick, count=self._count_locked,
                                   limiter=RateLimiter(config.source_rate_hz, config.source_burst,
                                                       config.max_sources),
                                   max_backlog_ticks=config.max_backlog_ticks, max_batch=config.max_batch)
        self._ticks = TickStats(window_s=1.0, cache_s=0.05)
        self._monitor = StateFaultMonitor(speed_factor=config.fault_speed_factor,
                                          range_tol_rad=config.fault_range_tol_rad,
                                          rest_speed_rad_s=config.rest_speed_rad_s,
                                          accel_factor=config.fault_accel_factor,
                                          accel_window_s=config.accel_window_s)
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
            o = self._sessions.owner
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
            return self._ticks.summary(time.monotonic())

    def state(self, request_seq: int = 0) -> P.State:
        """The state feedback message for the current core state."""
        p50, p99, worst = self.tick_stats()
        with self._lock:
            cs = self._core_state
            flags = self._flags & ~(_F.SETTLED | _F.MOVING | _F.COLLISION | _F.OWNED)
            flags |= cs.status_flags(self.config.rest_speed_rad_s)
            if self._sessions.owner is not None:
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
        with self._lock:
            self._ticks.restart()
        self._wall.run(self._period, duration, self._stop)

    def _record_tick(self, now: float) -> None:
        with self._lock:
            self._ticks.record(now)

    def _count_locked(self, **inc) -> None:
        with self._lock:
            self._count(**inc)

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
            self._vel.clear()

    def _tick(self, dt: float) -> None:
        with self._lock:
            try:
                self._tick_core(dt)
            except Exception as exc:       # noqa: BLE001 - the shell faults, never crashes
                self._fault(f"exception in the control tick: {type(exc).__name__}: {exc}")
            owner = self._sessions.owner
            if owner is not None and owner.lease_expired(self._t_ctrl, self.config.lease_s):
                self._end_session(f"lease expired ({self.config.lease_s:g} s without a datagram)")

    def _tick_core(self, dt: float) -> None:
        cs = self._core_state
        if self._mode == P.Mode.VELOCITY:
            vel = self._vel
            if vel.expire(self._t_ctrl):
                self._flags |= _F.WATCHDOG_STOP
                self._count(watchdog_stops=1)
                self._event("watchdog_stop", f"no velocity command for {self.config.watchdog_s:g} s")
            v_ref, limited = vel.next_reference(cs.theta, self.limits, dt)
            self._flags = self._flags | _F.LIMIT_BRAKE if limited else self._flags & ~_F.LIMIT_BRAKE
            if not np.all(np.isfinite(v_ref)):
                raise FloatingPointError(f"velocity reference {v_ref.tolist()} is not finite")
            action = vel.advance(v_ref)
            if action == "hold":           # at rest without a live command: hold position
                self.core.stop()
            elif action == "track":
                self.core.apply_velocity(v_ref.copy())
        self.core.step(dt)
        self._t_ctrl += dt
        new = self.core.state()
        if not all(np.all(np.isfinite(np.asarray(x, dtype=float)))
                   for x in (new.t, new.theta, new.theta_dot, new.strains, new.residuals)):
            self._fault("core state holds NaN or infinite values")   # keep the last finite state
            return
        self._core_state = cs = new
        what = self._monitor.check(cs, self.limits)
        if what is not None and not self._flags & _F.FAULT:
            self._fault(f"core state outside the {what} limits")

    def _enter_mode(self, mode: P.Mode) -> None:
        if mode == P.Mode.VELOCITY:
            if self._mode != P.Mode.VELOCITY:
                self._vel.enter(self._core_state.theta_dot)   # ramps down from the current speed
        elif self._mode == P.Mode.VELOCITY or mode == P.Mode.IDLE:
            self.core.stop()
            self._vel.clear()
        self._mode = mode

    # --------------------------------------------------------------- sessions
    def _end_session(self, reason: str) -> None:
        o = self._sessions.end(reason)
        if o is not None:
            self._event("session_end", f"session {o.sid:#010x}: {reason}")

    def _handshake(self, header, msg, addr) -> None:
        cfg, now = self.config, time.monotonic()
        if self._key is None and not is_loopback(addr):
            self._count(unauthenticated=1)
            return
        sessions = self._sessions
        sessions.expire_challenges(now)
        if isinstance(msg, P.Hello):
            nonce = sessions.challenge(addr, msg.client_nonce, now)
            self._send(P.Challenge(client_nonce=msg.client_nonce, server_nonce=nonce), addr, key=self._key)
            return
        if not isinstance(msg, P.OpenSession):
            self._count(malformed=1)      # Challenge/Welcome sent to the layer: protocol misuse
            return
        o = sessions.owner
        if o is not None and o.server_nonce == msg.server_nonce and o.addr == addr:
            self._transmit(o.welcome, addr)     # the Welcome was lost: same answer again
            return
        if not sessions.take_challenge(msg.server_nonce, addr, msg.client_nonce):
            self._count(replayed=1)             # unknown, used or expired challenge: a replay
            return
        if o is not None and o.addr != addr:
            if not (msg.takeover and cfg.allow_takeover):
                self._count(not_owner=1)
                left = max(o.lease_left(self._t_ctrl, cfg.lease_s), 0.0)
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
        sid = sessions.new_sid()
        skey = P.session_key(self._key, msg.client_nonce, msg.server_nonce, sid)
        welcome = P.Welcome(client_nonce=msg.client_nonce, session=sid, lease_s=cfg.lease_s)
        self._seq = P.seq_add(self._seq)
        data = P.encode(welcome, self._seq, time.monotonic(), key=self._key)
        sessions.owner = Session(sid, addr, skey, msg.server_nonce, data, self._t_ctrl)
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
            owner = self._sessions.owner
            session = None if sid == 0 else self._sessions.find(sid)   # the owner's or an ended one
            if sid != 0 and session is None and self._key is not None:
                self._count(unauthenticated=1)    # no key known for it: cannot be checked
                return
            key = self._key if sid == 0 else None if session is None else session.key
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
            if not isinstance(self.core, PayloadAwareCore):     # the capability is declared, not guessed
                return self._refuse(seq, P.Reason.UNSUPPORTED,
                                    f"core {type(self.core).__name__} has no payload model")
            self.core.set_payload(m)
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
            self._vel.command(v.value, self._t_ctrl)
            self._flags &= ~_F.WATCHDOG_STOP
            return self._accept(seq, v.code, v.text)
        s = check_setpoint(msg.theta, self.limits, max_speed=msg.max_speed,
                           max_accel=msg.max_accel, policy=self.config.policy)
        if not s.accepted:
            return self._refuse(seq, s.code, s.text)
        self.core.apply_setpoint(s.value, max_speed_rad_s=s.max_speed_rad_s,
                                 max_accel_rad_s2=s.max_accel_rad_s2)
        return self._accept(seq, s.code, s.text)


