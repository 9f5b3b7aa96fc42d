"""CDR bytes <-> message dicts for the rclpy backend, without rclpy's message objects.

The pump takes topic messages as CDR bytes and the publishers send CDR bytes: building and reading
rclpy's generated message objects cost more per message than walking the CDR here (measured on
std_msgs/String, Fast DDS: taking an object 8.6 µs and a raw message 3.6 µs; publishing an object
11.3 µs and bytes 8.6 µs). Only the simple cases are compiled: scalars, strings, nested messages,
byte arrays and numeric arrays (decoding), scalars, strings, nested messages and uint8[] as bytes
(encoding). Everything else, and any value the fast path does not expect (a missing field, a value
of another type, out of range, a string with NUL), goes through the Converter and rclpy as before,
so what a client sees (values and errors) does not change.

protocol/cdr.py (rosbags) also turns dicts into CDR, for the sim's cbor-raw and recordings; it is
not used here because its dicts follow rosbags' objects, not rclpy's conversions (what rclpy
coerces, rejects or defaults is what the rclpy backend must match).
"""

from __future__ import annotations

import struct
import sys
from math import isinf
from array import array
from collections.abc import Callable

from protocol.msgdefs import Field

HEADER = b'\x00\x01\x00\x00'   # CDR, little-endian: what rmw writes and reads
SCALARS = {
    'bool': '?', 'int8': 'b', 'uint8': 'B', 'byte': 'B', 'char': 'B', 'int16': 'h', 'uint16': 'H',
    'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q', 'float32': 'f', 'float64': 'd',
}
ENCODED = frozenset(SCALARS) - {'byte', 'char'}   # byte/char in rclpy are bytes/str, not ints
TYPECODES = {'int8': 'b', 'uint8': 'B', 'int16': 'h', 'uint16': 'H', 'int32': 'i', 'uint32': 'I',
             'int64': 'q', 'uint64': 'Q', 'float32': 'f', 'float64': 'd'}
FLT_MAX = 3.402823466e+38
U32 = struct.Struct('<I')
LITTLE = sys.byteorder == 'little' and all(array(c).itemsize == struct.calcsize(c) for c in TYPECODES.values())


class Slow(Exception):
    """The fast path does not handle this message: take the Converter's path."""


def _pad(pos: int, align: int) -> int:
    return (-(pos - 4)) % align      # alignment counts from the end of the encapsulation header


# --- decoding ---------------------------------------------------------------------------------

def reader(plan: Callable, cls) -> Callable[[bytes], dict] | None:
    """A function from CDR bytes to the dict ``Converter.to_dict`` makes, or None (not compiled).

    ``plan(cls)`` gives ``(name, Field, sub class or None)`` per field, as the Converter's."""
    if not LITTLE:
        return None
    read = _reader(plan, cls)
    if read is None:
        return None

    def decode(data: bytes) -> dict:
        if data[:2] != b'\x00\x01':
            raise Slow('not little-endian CDR')
        out, pos = read(data, 4)
        if pos > len(data):
            raise Slow('short message')
        return out
    return decode


def _ops(plan, cls, op_for) -> tuple | None:
    """``(name, op)`` per field of cls, or None when a field has no compiled op."""
    ops = []
    for name, f, sub in plan(cls):
        op = op_for(plan, f, sub)
        if op is None:
            return None
        ops.append((name, op))
    return tuple(ops)


def _reader(plan, cls):
    ops = _ops(plan, cls, _read_op)
    if ops is None:
        return None

    def read(data: bytes, pos: int) -> tuple[dict, int]:
        out = {}
        for name, op in ops:
            out[name], pos = op(data, pos)
        return out, pos
    return read


def _read_op(plan, f: Field, sub):
    if sub is not None:
        if f.array is not None:
            return None
        return _reader(plan, sub)
    if f.array is None:
        if f.type == 'string':
            return _read_string
        code = SCALARS.get(f.type)
        if code is None:
            return None
        s = struct.Struct('<' + code)
        size, unpack = s.size, s.unpack_from

        def scalar(data, pos):
            pos += _pad(pos, size)
            return unpack(data, pos)[0], pos + size
        return scalar
    if f.is_bytes:
        return _read_bytes(f.array)
    code = TYPECODES.get(f.type)
    if code is None:
        return None                 # bool and string arrays
    return _read_numbers(code, f.array)


def _length(data: bytes, pos: int) -> tuple[int, int]:
    """A string's or sequence's length (uint32, 4-aligned) and where its contents start."""
    pos += _pad(pos, 4)
    return U32.unpack_from(data, pos)[0], pos + 4


def _read_string(data: bytes, pos: int):
    n, pos = _length(data, pos)
    end = pos + n
    if n == 0 or end > len(data):
        raise Slow('bad string length')
    if data.find(b'\x00', pos, end - 1) >= 0:
        raise Slow('NUL in a string')
    try:   # a long string is decoded in place, a short one from a slice (cheaper to make)
        return (str(memoryview(data)[pos:end - 1], 'utf-8') if n > 512 else data[pos:end - 1].decode()), end
    except UnicodeDecodeError:
        raise Slow('not UTF-8') from None


def _read_bytes(fixed: int):
    def read(data: bytes, pos: int):
        n = fixed
        if not n:
            n, pos = _length(data, pos)
        end = pos + n
        if end > len(data):
            raise Slow('short byte array')
        return data[pos:end], end
    return read


def _read_numbers(code: str, fixed: int):
    size = struct.calcsize(code)

    def read(data: bytes, pos: int):
        n = fixed
        if not n:
            n, pos = _length(data, pos)
        if n:
            pos += _pad(pos, size)
        end = pos + n * size
        if end > len(data):
            raise Slow('short array')
        return array(code, data[pos:end]).tolist(), end
    return read


# --- encoding ---------------------------------------------------------------------------------

def writer(plan: Callable, cls) -> Callable[[dict], bytes] | None:
    """A function from a message dict to CDR bytes, or None (not compiled); raises Slow for any
    dict that ``Converter.from_dict`` would not take exactly as given."""
    if not LITTLE:
        return None
    write = _writer(plan, cls)
    if write is None:
        return None
    if _fixed_size(plan, cls):
        # rmw_fastrtps pads messages of a fixed size to a multiple of 4 bytes, as serialize_message shows
        def encode(msg: dict) -> bytes:
            parts = [HEADER]
            pad = -write(msg, parts, 4) % 4
            if pad:
                parts.append(_ZEROS[:pad])
            return b''.join(parts)
        return encode

    def encode(msg: dict) -> bytes:
        parts = [HEADER]
        write(msg, parts, 4)
        return b''.join(parts)
    return encode


def _fixed_size(plan, cls) -> bool:
    return all((f.array is None or f.array > 0) and f.type not in ('string', 'wstring')
               and (sub is None or _fixed_size(plan, sub)) for _, f, sub in plan(cls))


def _writer(plan, cls):
    ops = _ops(plan, cls, _write_op)
    if not ops:
        return None     # not compiled, or an empty message: one placeholder byte on the wire

    def write(msg, parts: list, pos: int) -> int:
        if type(msg) is not dict or len(msg) < len(ops):
            raise Slow('not a dict with every field')
        for name, op in ops:
            value = msg.get(name, Slow)
            if value is Slow:
                raise Slow('a field is missing')   # rclpy's class default applies
            pos = op(value, parts, pos)
        return pos
    return write


_ZEROS = bytes(8)


def _write_op(plan, f: Field, sub):
    if sub is not None:
        return None if f.array is not None else _writer(plan, sub)
    if f.array is not None:
        if f.array == 0 and not f.bound and f.type == 'uint8':
            return _write_bytes
        return None
    if f.type == 'string':
        return _write_string(f.string_bound)
    if f.type not in ENCODED:
        return None
    s = struct.Struct('<' + SCALARS[f.type])
    size, pack = s.size, s.pack
    if f.type == 'bool':
        def check(v):
            if type(v) is not bool:
                raise Slow('not a bool')
            return v
    elif f.type in ('float32', 'float64'):
        single = f.type == 'float32'

        def check(v):
            if type(v) is not float:
                if type(v) is not int:
                    raise Slow('not a number')
                try:
                    v = float(v)
                except OverflowError:
                    raise Slow('too large') from None
            if single and (v < -FLT_MAX or v > FLT_MAX) and not isinf(v):   # rclpy's check
                raise Slow('out of float32 range')
            return v
    else:
        def check(v):
            if type(v) is not int:
                raise Slow('not an int')
            return v

    def scalar(v, parts, pos):
        pad = _pad(pos, size)
        if pad:
            parts.append(_ZEROS[:pad])
        try:
            parts.append(pack(check(v)))
        except struct.error:
            raise Slow('out of range') from None
        return pos + pad + size
    return scalar


def _write_string(bound: int):
    def write(v, parts, pos):
        if type(v) is not str or (bound and len(v) > bound) or '\x00' in v:
            raise Slow('not a plain string')
        try:
            data = v.encode()
        except UnicodeEncodeError:
            raise Slow('not encodable') from None
        pos = _write_length(len(data) + 1, parts, pos)
        parts.append(data)
        parts.append(b'\x00')
        return pos + len(data) + 1
    return write


def _write_bytes(v, parts, pos):
    if type(v) is not bytes:
        raise Slow('not bytes')
    pos = _write_length(len(v), parts, pos)
    parts.append(v)
    return pos + len(v)


def _write_length(n: int, parts: list, pos: int) -> int:
    """A string's or sequence's length (uint32, 4-aligned); where its contents start."""
    pad = _pad(pos, 4)
    if pad:
        parts.append(_ZEROS[:pad])
    parts.append(U32.pack(n))
    return pos + pad + 4
