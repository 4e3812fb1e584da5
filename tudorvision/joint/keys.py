"""Keys of the joint protocol: key files, HMAC-SHA256 tags, nonces and session keys.

A layer with a key authenticates every datagram: outside a session with the
long-term key of the key file, inside one with the session key that
:func:`session_key` derives from it, the two handshake nonces and the
session id (see :mod:`tudorvision.joint.protocol` for the wire format).

Examples
--------
>>> body = b"header and payload"
>>> tag = hmac_tag(bytes(32), body)
>>> len(tag) == TAG_SIZE, verify_tag(bytes(32), body, tag), verify_tag(bytes(32), body + b"!", tag)
(True, True, False)
"""
from __future__ import annotations

import hmac
import os

from .._checks import TudorVisionError

__all__ = ["TAG_SIZE", "NONCE_SIZE", "KEY_SIZE", "check_key", "check_nonce", "hmac_tag", "verify_tag",
           "new_nonce", "session_key", "write_key_file", "read_key_file"]

TAG_SIZE = 32                       # HMAC-SHA256
NONCE_SIZE = 16
KEY_SIZE = 32                       # bytes of a key file's key
_U32 = 0xFFFFFFFF


def check_key(key, name: str = "key") -> bytes | None:
    """Check a key: ``None`` (no authentication) or at least 16 bytes.

    Parameters
    ----------
    key : bytes or bytearray or None
        The key to check.
    name : str
        Argument name used in the error message.

    Returns
    -------
    bytes or None
        The key as ``bytes``, or ``None``.

    Raises
    ------
    ValueError
        If ``key`` is not bytes or shorter than 16 bytes.
    """
    if key is None:
        return None
    if not isinstance(key, (bytes, bytearray)) or len(key) < 16:
        raise ValueError(f"{name}: expected at least 16 bytes, got {key!r:.40}")
    return bytes(key)


def check_nonce(value, name: str) -> bytes:
    """Check a handshake nonce: exactly :data:`NONCE_SIZE` bytes.

    Parameters
    ----------
    value : bytes-like
        The nonce.
    name : str
        Argument name used in the error message.

    Returns
    -------
    bytes
        The nonce as ``bytes``.

    Raises
    ------
    ValueError
        If the nonce does not hold :data:`NONCE_SIZE` bytes.
    """
    value = bytes(value)
    if len(value) != NONCE_SIZE:
        raise ValueError(f"{name}: expected {NONCE_SIZE} bytes, got {len(value)}")
    return value


def hmac_tag(key: bytes, body: bytes) -> bytes:
    """The HMAC-SHA256 tag of ``body`` under ``key``.

    Parameters
    ----------
    key : bytes
        Long-term or session key (checked by the caller, :func:`check_key`).
    body : bytes
        Header and payload of a datagram.

    Returns
    -------
    bytes
        :data:`TAG_SIZE` bytes.
    """
    return hmac.digest(key, body, "sha256")


def verify_tag(key: bytes, body: bytes, tag: bytes) -> bool:
    """True if ``tag`` is the HMAC-SHA256 tag of ``body`` under ``key`` (constant-time comparison).

    Parameters
    ----------
    key : bytes
        Long-term or session key.
    body : bytes
        Header and payload of a datagram.
    tag : bytes
        The tag that came with it.

    Returns
    -------
    bool
    """
    return hmac.compare_digest(hmac.digest(key, body, "sha256"), tag)


def new_nonce() -> bytes:
    """A fresh random nonce (``os.urandom``, 16 bytes).

    Returns
    -------
    bytes
        :data:`NONCE_SIZE` random bytes.
    """
    return os.urandom(NONCE_SIZE)


def session_key(key: bytes | None, client_nonce: bytes, server_nonce: bytes, session: int) -> bytes | None:
    """The key of one session: ``HMAC-SHA256(key, b"TDJL session" + nonces + session id)``.

    Parameters
    ----------
    key : bytes or None
        The long-term key; ``None`` for an unauthenticated layer.
    client_nonce, server_nonce : bytes
        The two nonces of the handshake (16 bytes each).
    session : int
        Session id (uint32).

    Returns
    -------
    bytes or None
        32 bytes; ``None`` without a long-term key.

    Raises
    ------
    ValueError
        If the key is shorter than 16 bytes or a nonce is not 16 bytes long.

    Examples
    --------
    >>> k = session_key(bytes(32), bytes(16), bytes(range(16)), 7)
    >>> len(k), k == session_key(bytes(32), bytes(16), bytes(range(16)), 8)
    (32, False)
    """
    key = check_key(key)
    if key is None:
        return None
    info = (b"TDJL session" + check_nonce(client_nonce, "client_nonce")
            + check_nonce(server_nonce, "server_nonce"))
    return hmac.digest(key, info + (session & _U32).to_bytes(4, "big"), "sha256")


def write_key_file(path, *, overwrite: bool = False) -> bytes:
    """Write a fresh random key (:data:`KEY_SIZE` bytes from ``os.urandom``) as one hex line.

    The file is created with permissions 0600 (owner read/write only); an
    existing file is refused unless ``overwrite`` (then it is replaced
    atomically by a new 0600 file).

    Parameters
    ----------
    path : str or os.PathLike
        Where to write the key.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    bytes
        The key.

    Raises
    ------
    TudorVisionError
        If the file exists (without ``overwrite``) or cannot be written.
    """
    path = os.fspath(path)
    key = os.urandom(KEY_SIZE)
    target = path + ".tmp" if overwrite else path
    try:
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise TudorVisionError(f"{target}: exists; refusing to overwrite a key file") from None
    except OSError as err:
        raise TudorVisionError(f"{target}: cannot create the key file: {err.strerror}") from None
    try:
        os.fchmod(fd, 0o600)
        os.write(fd, key.hex().encode("ascii") + b"\n")
        os.fsync(fd)
    except OSError as err:
        os.close(fd)
        os.unlink(target)
        raise TudorVisionError(f"{target}: cannot write the key file: {err.strerror}") from None
    os.close(fd)
    if overwrite:
        os.replace(target, path)
    return key


def read_key_file(path) -> bytes:
    """Read a key written by :func:`write_key_file` (hex, at least 16 bytes).

    Parameters
    ----------
    path : str or os.PathLike
        The key file.

    Returns
    -------
    bytes
        The key.

    Raises
    ------
    TudorVisionError
        If the file is missing, readable by group or others (like ssh, the
        key is refused: ``chmod 600`` it), or does not hold a hex key.
    """
    path = os.fspath(path)
    try:
        st = os.stat(path)
        with open(path, "rb") as fh:
            raw = fh.read(4096)
    except OSError as err:
        raise TudorVisionError(f"{path}: cannot read the key file: {err.strerror}") from None
    if st.st_mode & 0o077:
        raise TudorVisionError(f"{path}: key file permissions {st.st_mode & 0o777:03o} let others "
                               f"read it; chmod 600 it")
    try:
        key = bytes.fromhex(raw.decode("ascii").strip())
    except (UnicodeDecodeError, ValueError):
        key = b""
    if len(key) < 16:
        raise TudorVisionError(f"{path}: not a key file (expected one line of at least 32 hex digits)")
    return key
