"""Camera images made to measure: decode a sensor_msgs Image or CompressedImage, resize, encode
as JPEG or PNG (Pillow and numpy).

A 640x480 camera's 36 KiB JPEGs at 10 Hz need 2.9 Mbit/s; a home line of 1 Mbit/s can carry
them only smaller or rougher (320x240 at quality 50 is ~8 KiB). The fan-out calls ``render``
at most once per message and ``Target``, whoever asked (subscribers with the ``image`` field
of subscribe, viewers of ``/stream``), so twelve viewers of one size cost one encode.
A JPEG the target would not shrink passes unchanged (``render``). A JPEG is decoded with Pillow's draft mode, which lets the decoder scale by 1/2, 1/4 or 1/8
while decoding: a 640x480 frame asked for at 160x120 is never built at full size.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
from PIL import Image

from protocol.ops import ImageSpec

from . import grids

RAW = 'sensor_msgs/msg/Image'
COMPRESSED = 'sensor_msgs/msg/CompressedImage'
TYPES = (RAW, COMPRESSED)
SIZED = (*TYPES, grids.GRID)   # what the ``image`` field of subscribe applies to

# encoding -> (numpy dtype, channels, channels swapped from BGR)
ENCODINGS = {
    'rgb8': ('u1', 3, False), 'rgba8': ('u1', 4, False), 'bgr8': ('u1', 3, True),
    'bgra8': ('u1', 4, True), 'mono8': ('u1', 1, False), '8uc1': ('u1', 1, False),
    '8uc3': ('u1', 3, True), '8uc4': ('u1', 4, True), 'mono16': ('u2', 1, False),
    '16uc1': ('u2', 1, False), '32fc1': ('f4', 1, False),
}


class ImageError(ValueError):
    """The message holds no image this module can read (its words say why)."""


@dataclass(frozen=True, slots=True)
class Target:
    """One made-to-measure image. width/height None: the image's own. fit: a missing side
    follows the aspect ratio and the image is never enlarged (what a subscribe asks);
    otherwise the sides are taken as given (web_video_server's width= and height=)."""
    width: int | None = None
    height: int | None = None
    quality: int = 95          # JPEG quality 1-100; for PNG the zlib level 0-9
    format: str = 'jpeg'       # 'jpeg' or 'png'
    fit: bool = False

    @classmethod
    def of(cls, spec: ImageSpec) -> Target:
        return cls(spec.width, spec.height, spec.quality, 'jpeg', True)

    def size(self, width: int, height: int) -> tuple[int, int]:
        w, h = self.width, self.height
        if not self.fit:
            return w or width, h or height
        if w is None and h is None:
            return width, height
        scale = min(w / width if w else 1.0, h / height if h else 1.0, 1.0)
        return max(1, round(width * scale)), max(1, round(height * scale))


def content_type(msg: dict) -> str | None:
    """The MIME type of a CompressedImage's data as web_video_server names it (None: neither)."""
    fmt = str(msg.get('format', '')).lower()
    if 'jpeg' in fmt or 'jpg' in fmt:
        return 'image/jpeg'
    if 'png' in fmt:
        return 'image/png'
    return None


def render(msg: dict, type: str, target: Target) -> bytes | dict:
    """The message's image as ``target`` asks; raises ImageError. A map (OccupancyGrid) comes back
    as a smaller map, a message dict (grids.py). A JPEG that a fitting target
    would not make smaller is passed as it is: re-encoding a 160x120 camera's 2.5 KiB frames
    at another quality saves a few hundred bytes for a millisecond of the event loop each, which
    thirty stations' cameras at 5 Hz would turn into a fifth of a core."""
    if type == grids.GRID:
        try:
            return grids.shrink(msg, target.width, target.height)
        except (grids.GridError, ValueError, TypeError) as e:
            raise ImageError(f'cannot shrink the map: {e}') from None
    if target.fit and type == COMPRESSED and target.format == 'jpeg':
        data = msg.get('data')
        if isinstance(data, (bytes, bytearray, memoryview)) and data:
            try:
                header = Image.open(io.BytesIO(data))   # reads the header only
            except Exception:   # Pillow raises many kinds for bad bytes
                raise ImageError(f'cannot decode the CompressedImage ({msg.get("format")!r})') from None
            if header.format == 'JPEG' and target.size(*header.size) == header.size:
                return bytes(data)
    image = decode(msg, type, target)
    size = target.size(*image.size)
    if size != image.size:
        image = image.resize(size, Image.BILINEAR)
    buf = io.BytesIO()
    if target.format == 'png':
        image.save(buf, 'PNG', compress_level=max(0, min(9, target.quality)))
    else:
        if image.mode not in ('RGB', 'L'):
            image = image.convert('RGB')
        image.save(buf, 'JPEG', quality=max(1, min(100, target.quality)))
    return buf.getvalue()


def decode(msg: dict, type: str, target: Target) -> Image.Image:
    if type == COMPRESSED:
        data = msg.get('data')
        if not isinstance(data, (bytes, bytearray, memoryview)) or not data:
            raise ImageError('the CompressedImage has no data')
        try:
            image = Image.open(io.BytesIO(data))
            if image.format == 'JPEG' and (target.width or target.height):
                image.draft('RGB', target.size(*image.size))   # scaled while decoding
            image.load()
        except Exception as e:   # Pillow raises many kinds for bad bytes
            raise ImageError(f'cannot decode the CompressedImage ({msg.get("format")!r}): {e}') from None
        return image if image.mode in ('RGB', 'L', 'RGBA') else image.convert('RGB')
    if type == RAW:
        return _raw(msg)
    raise ImageError(f'{type} is not an image type ({", ".join(TYPES)})')


def _raw(msg: dict) -> Image.Image:
    encoding = str(msg.get('encoding', '')).lower()
    if encoding not in ENCODINGS:
        raise ImageError(f'image encoding {encoding!r} is not supported ({", ".join(ENCODINGS)})')
    kind, channels, bgr = ENCODINGS[encoding]
    width, height, step = int(msg.get('width', 0)), int(msg.get('height', 0)), int(msg.get('step', 0))
    data = msg.get('data') or b''
    itemsize = np.dtype(kind).itemsize
    row = width * channels * itemsize
    if width <= 0 or height <= 0 or step < row or len(data) < step * height:
        raise ImageError(f'image of {width}x{height}, step {step} does not fit its {len(data)} bytes')
    rows = np.frombuffer(data, np.uint8, count=step * height).reshape(height, step)[:, :row]
    order = '>' if msg.get('is_bigendian') else '<'
    pixels = np.ascontiguousarray(rows).view(np.dtype(kind).newbyteorder(order)).reshape(height, width, channels)
    if kind == 'u2':
        pixels = (pixels >> 8).astype(np.uint8)
    elif kind == 'f4':   # as web_video_server: scaled so the largest value is white
        top = float(np.nanmax(pixels)) if pixels.size else 0.0
        pixels = np.nan_to_num(pixels * (255.0 / top if top > 0 else 1.0)).clip(0, 255).astype(np.uint8)
    if bgr:
        pixels = pixels[..., [2, 1, 0, 3][:channels]]
    if channels == 1:
        return Image.fromarray(np.ascontiguousarray(pixels[..., 0]), 'L')
    return Image.fromarray(np.ascontiguousarray(pixels), 'RGB' if channels == 3 else 'RGBA')
