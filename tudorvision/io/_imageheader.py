"""Image dimensions from the file header, without decoding (PNG, JPEG, BMP, PNM).

OpenCV cannot report an image's size without decoding it, and decoding a
small file that declares 30000 x 30000 pixels allocates gigabytes. The
readers call :func:`image_size_from_header` first and refuse images over a
pixel limit (:data:`DEFAULT_MAX_PIXELS`, raised with ``max_pixels=`` or the
CLI's ``--max-pixels``).
"""
from __future__ import annotations

import struct

__all__ = ["DEFAULT_MAX_PIXELS", "HEADER_BYTES", "image_size_from_header", "check_pixel_limit"]

#: Default largest image accepted by the sequence readers: 100 megapixels.
DEFAULT_MAX_PIXELS = 100_000_000

#: Bytes of a file that :func:`image_size_from_header` looks at (JPEG EXIF blocks can be long).
HEADER_BYTES = 1 << 18

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic); not DHT/JPG/DAC
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def image_size_from_header(data: bytes) -> tuple[int, int] | None:
    """``(width, height)`` in pixels declared by an image file's header.

    Parameters
    ----------
    data : bytes
        The first bytes of the file (:data:`HEADER_BYTES` are enough for
        PNG, JPEG, BMP and PGM/PPM files).

    Returns
    -------
    tuple of int or None
        ``(width, height)`` for PNG (IHDR), JPEG (the first SOF segment), BMP
        and binary/ASCII PNM headers; None for other formats or a header
        too short or malformed to say (the decoder then decides).

    Examples
    --------
    >>> import struct
    >>> png = b"\\x89PNG\\r\\n\\x1a\\n" + struct.pack(">I4sII", 13, b"IHDR", 30000, 30000)
    >>> image_size_from_header(png)
    (30000, 30000)
    >>> image_size_from_header(b"P5\\n# comment\\n640 480\\n255\\n")
    (640, 480)
    """
    data = bytes(data[:HEADER_BYTES])
    if data.startswith(_PNG_SIGNATURE):
        if len(data) >= 24 and data[12:16] == b"IHDR":
            w, h = struct.unpack(">II", data[16:24])
            return int(w), int(h)
        return None
    if data.startswith(b"\xff\xd8"):
        return _jpeg_size(data)
    if data.startswith(b"BM") and len(data) >= 26:
        w, h = struct.unpack("<ii", data[18:26])
        return abs(int(w)), abs(int(h))
    if len(data) >= 2 and data[0:1] == b"P" and data[1:2] in b"123456":
        return _pnm_size(data)
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    pos = 2
    n = len(data)
    for _ in range(10000):   # segments; bounded against crafted loops
        while pos < n and data[pos] == 0xFF:
            pos += 1          # fill bytes before a marker
        if pos >= n:
            return None
        marker = data[pos]
        pos += 1
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            continue          # markers without a length
        if marker in (0xD9, 0xDA) or pos + 2 > n:
            return None       # end of image or start of scan before any SOF
        (length,) = struct.unpack(">H", data[pos:pos + 2])
        if length < 2:
            return None
        if marker in _SOF:
            if pos + 7 > n:
                return None
            h, w = struct.unpack(">HH", data[pos + 3:pos + 7])
            return int(w), int(h)
        pos += length
        if pos < n and data[pos] != 0xFF:
            return None
    return None


def _pnm_size(data: bytes) -> tuple[int, int] | None:
    tokens: list[bytes] = []
    pos, n = 2, len(data)
    while len(tokens) < 2 and pos < n:
        c = data[pos:pos + 1]
        if c == b"#":
            end = data.find(b"\n", pos)
            pos = n if end < 0 else end + 1
        elif c.isspace():
            pos += 1
        else:
            start = pos
            while pos < n and not data[pos:pos + 1].isspace() and data[pos:pos + 1] != b"#":
                pos += 1
            tokens.append(data[start:pos])
    if len(tokens) < 2 or not all(t.isdigit() for t in tokens):
        return None
    return int(tokens[0]), int(tokens[1])


def check_pixel_limit(size: tuple[int, int] | None, max_pixels: int | None) -> str | None:
    """Why an image of ``size`` is refused, or None when it is accepted.

    Parameters
    ----------
    size : tuple of int or None
        ``(width, height)`` from :func:`image_size_from_header`; None passes.
    max_pixels : int or None
        Largest accepted ``width * height``; None disables the limit.

    Returns
    -------
    str or None
        A reason in words (for :class:`~tudorvision.io._index.ImageProblem`).

    Examples
    --------
    >>> check_pixel_limit((30000, 30000), DEFAULT_MAX_PIXELS)
    'header declares 30000x30000 pixels (900 megapixels), over the limit of 100 megapixels (raise it with --max-pixels)'
    >>> check_pixel_limit((640, 480), DEFAULT_MAX_PIXELS) is None
    True
    """
    if size is None:
        return None
    w, h = size
    if w <= 0 or h <= 0:
        return f"header declares an empty image ({w}x{h} pixels)"
    if max_pixels is not None and w * h > max_pixels:
        return (f"header declares {w}x{h} pixels ({w * h / 1e6:.0f} megapixels), over the limit of "
                f"{max_pixels / 1e6:g} megapixels (raise it with --max-pixels)")
    return None
