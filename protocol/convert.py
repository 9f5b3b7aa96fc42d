"""Message values: the JSON rules (validate, fill defaults) and CBOR typed arrays, driven by msgdefs.

Per message type the work is compiled once into closures (cached per Definitions), so converting
a message is a walk over precomputed field tables, not an interpretation of its definition.
CDR lives in cdr.py and is re-exported here.
"""

from __future__ import annotations

import array
import binascii
import math
import operator
import sys

import cbor2
from pybase64 import b64decode   # SIMD base64: images are megabytes of it

from .cdr import from_cdr, to_cdr
from .compiled import B64_TYPES, MISSING, compiled, default_message, field_default
from .errors import ConversionError, json_type, shown
from .msgdefs import FLOATS, INTEGERS, Definitions, Field, MsgDef

__all__ = ['default_message', 'from_args', 'from_cdr', 'from_json', 'to_cbor', 'to_cdr']

NAN = math.nan
F32_MAX = 3.4028234663852886e38
TIME_TYPES = frozenset({'builtin_interfaces/msg/Time', 'builtin_interfaces/msg/Duration'})
TIME_ALIASES = {'secs': 'sec', 'nsecs': 'nanosec'}
# RFC 8746 little-endian typed-array tag, array.array typecode and numpy dtype per element type
CBOR_TAGS = {'float64': (86, 'd', '<f8'), 'float32': (85, 'f', '<f4'), 'int8': (72, 'b', 'i1'),
             'int16': (77, 'h', '<i2'), 'uint16': (69, 'H', '<u2'), 'int32': (78, 'i', '<i4'),
             'uint32': (70, 'I', '<u4'), 'int64': (79, 'q', '<i8'), 'uint64': (71, 'Q', '<u8')}
_LITTLE = sys.byteorder == 'little'
_FLOAT_OK = frozenset({float})
_NUMBER_OK = frozenset({float, int, type(None)})
_INT_OK = frozenset({int})
_BOOL_OK = frozenset({bool})
_STR_OK = frozenset({str})


class _Bad(Exception):
    """A conversion failure deep in a message; parents add their path segment on the way out."""

    def __init__(self, what: str, unknown: str = '') -> None:
        self.what = what          # 'must be a number, got string'
        self.unknown = unknown    # for unknown fields: the message type that lacks it
        self.parts: list = []     # path segments, innermost first

    def error(self, prefix: str) -> ConversionError:
        path = prefix
        for part in reversed(self.parts):
            path = f'{path}[{part}]' if isinstance(part, int) else f'{path}.{part}' if path else part
        if self.unknown:
            return ConversionError(f"unknown field '{path}' ({self.unknown} has no such field)", path=path)
        return ConversionError(f"field '{path}' {self.what}" if path else f'message {self.what}', path=path)


# --- JSON in: validate and fill defaults --------------------------------------------------------

def _float64(v):
    t = type(v)
    if t is float:
        return v
    if v is None:
        return NAN
    if t is not bool and hasattr(t, '__float__'):  # int, numpy scalars
        try:
            return float(v)
        except OverflowError:
            raise _Bad(f'is out of range for float64, got {shown(v)}') from None
        except (TypeError, ValueError):
            pass
    raise _Bad(f'must be a number, got {json_type(v)}')


def _in_f32(x: float) -> bool:
    return -F32_MAX <= x <= F32_MAX or math.isnan(x) or math.isinf(x)


def _float32(v):
    x = _float64(v)
    if _in_f32(x):
        return x
    raise _Bad(f'is out of range for float32, got {shown(v)}')


def _boolean(v):
    if type(v) is bool:
        return v
    raise _Bad(f'must be a boolean, got {json_type(v)}')


def _integer(typ: str):
    lo, hi = INTEGERS[typ]
    article = 'an' if typ.startswith('int') else 'a'

    def check(v):
        if type(v) is not int:
            if type(v) is bool or isinstance(v, float) or not hasattr(type(v), '__index__'):
                raise _Bad(f'must be an integer, got {json_type(v)}')
            v = operator.index(v)  # numpy integers, IntEnum
        if lo <= v <= hi:
            return v
        raise _Bad(f'must be {article} {typ} ({lo}..{hi}), got {shown(v)}')
    return check


def _string(bound: int):
    def check(v):
        if type(v) is str:
            if bound and len(v) > bound:
                raise _Bad(f'must be at most {bound} characters, got {len(v)}')
            return v
        raise _Bad(f'must be a string, got {json_type(v)}')
    return check


def _scalar_check(f: Field):
    if f.type == 'float64':
        return _float64
    if f.type == 'float32':
        return _float32
    if f.type in INTEGERS:
        return _integer(f.type)
    if f.type == 'bool':
        return _boolean
    return _string(f.string_bound)


def _length_check(f: Field):
    if f.array:
        n = f.array

        def check(v):
            if len(v) != n:
                raise _Bad(f'must have exactly {n} elements, got {len(v)}')
    elif f.bound:
        n = f.bound

        def check(v):
            if len(v) > n:
                raise _Bad(f'must have at most {n} elements, got {len(v)}')
    else:
        check = None
    return check


def _each(values, item) -> list:
    """The slow path: convert item by item, naming the index that fails."""
    out = []
    for i, x in enumerate(values):
        try:
            out.append(item(x))
        except _Bad as e:
            e.parts.append(i)
            raise
    return out


def _as_list(v) -> list:
    if type(v) is list:
        return v
    if type(v) is tuple:
        return list(v)
    raise _Bad(f'must be an array, got {json_type(v)}')


def _bytes_check(f: Field, as_list: bool):
    """uint8[]/char[] -> bytes (from base64, a byte string or a list of ints); byte[] -> list of ints."""
    length = _length_check(f)
    what = 'must be a base64 string or an array of integers 0..255'
    octet = _integer('uint8')

    def check(v):
        t = type(v)
        if t is str:
            try:
                b = b64decode(v, validate=True)
            except (binascii.Error, ValueError) as e:
                raise _Bad(f'{what}, got a string that is not base64 ({e})') from None
        elif t is bytes:
            b = v
        elif t is list or t is tuple or t is bytearray or t is memoryview:
            try:
                b = bytes(v)
            except (ValueError, TypeError):
                b = bytes(_each(v, octet))
        else:
            raise _Bad(f'{what}, got {json_type(v)}')
        if length is not None:
            length(b)
        return list(b) if as_list else b
    return check


def _array_check(defs: Definitions, f: Field):
    """Arrays: a C-speed type census decides; lists already right are kept as they are."""
    if f.type in B64_TYPES:
        return _bytes_check(f, as_list=False)
    if f.type == 'byte':
        return _bytes_check(f, as_list=True)
    length = _length_check(f)
    if not f.primitive:
        item = _json_converter(defs, defs.msg(f.type))

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            try:
                return [item(x) for x in v]
            except _Bad:
                return _each(v, item)
        return check

    item = _scalar_check(f)
    if f.type in FLOATS:
        f32 = f.type == 'float32'

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            types = set(map(type, v))
            if not types <= _FLOAT_OK:
                if not types <= _NUMBER_OK:
                    return _each(v, item)
                try:
                    v = [NAN if x is None else float(x) for x in v]
                except OverflowError:
                    return _each(v, item)
            if f32 and v and (any(map(math.isnan, v)) or not -F32_MAX <= min(v) <= max(v) <= F32_MAX):
                return _each(v, item)  # NaN/inf are fine, finite values beyond float32 are not
            return v
        return check

    if f.type in INTEGERS:
        lo, hi = INTEGERS[f.type]

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            if set(map(type, v)) <= _INT_OK and (not v or (lo <= min(v) and max(v) <= hi)):
                return v
            return _each(v, item)
        return check

    ok = _BOOL_OK if f.type == 'bool' else _STR_OK
    bound = f.string_bound

    def check(v):
        v = _as_list(v)
        if length is not None:
            length(v)
        if set(map(type, v)) <= ok and not (bound and v and max(map(len, v)) > bound):
            return v
        return _each(v, item)
    return check


def _field_check(defs: Definitions, f: Field):
    if f.array is not None:
        return _array_check(defs, f)
    if f.primitive:
        return _scalar_check(f)
    return _json_converter(defs, defs.msg(f.type))


def _json_converter(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        fields = tuple((f.name, _field_check(defs, f), *field_default(defs, f, msgdef.type))
                       for f in msgdef.fields)
        names = frozenset(f.name for f in msgdef.fields)
        typename = msgdef.type

        def convert(v):
            if type(v) is not dict:
                raise _Bad(f'must be an object, got {json_type(v)}')
            out = {}
            seen = 0
            for name, check, const, factory in fields:
                x = v.get(name, MISSING)
                if x is MISSING:
                    out[name] = const if factory is None else factory()
                    continue
                seen += 1
                try:
                    out[name] = check(x)
                except _Bad as e:
                    e.parts.append(name)
                    raise
            if seen != len(v):
                for key in v:
                    if key not in names:
                        e = _Bad('', unknown=typename)
                        e.parts.append(str(key))
                        raise e
            return out

        if typename in TIME_TYPES:
            plain = convert

            def convert(v):  # Time/Duration also accept ROS 1 secs/nsecs
                if type(v) is dict and ('secs' in v or 'nsecs' in v):
                    v = {TIME_ALIASES.get(k, k): x for k, x in v.items()}
                return plain(v)
        return convert
    return compiled(defs, 'json', msgdef, make)


def from_json(defs: Definitions, msgdef: MsgDef, value, path: str = '') -> dict:
    """Validate a JSON message value and fill defaults; ConversionError names the field path."""
    convert = _json_converter(defs, msgdef)
    try:
        return convert(value)
    except _Bad as e:
        raise e.error(path) from None


def from_args(defs: Definitions, msgdef: MsgDef, args, path: str = 'args') -> dict:
    """Service/goal args: null (all defaults), an object, or a list of values in field order."""
    if args is None:
        return default_message(defs, msgdef)
    if type(args) is list:
        names = [f.name for f in msgdef.fields]
        if len(args) > len(names):
            raise ConversionError(f"field '{path}' has {len(args)} values but {msgdef.type} has "
                                  f'{len(names)} fields', path=path)
        args = dict(zip(names, args, strict=False))
    return from_json(defs, msgdef, args, path)


# --- CBOR: numeric arrays as RFC 8746 typed arrays ----------------------------------------------

def _packer(typ: str):
    tag, code, le_dtype = CBOR_TAGS[typ]
    Tag = cbor2.CBORTag

    def pack(v):
        if type(v) is array.array and v.typecode == code:
            a = v
        elif hasattr(v, 'dtype'):
            return Tag(tag, v.astype(le_dtype, copy=False).tobytes())
        else:
            a = array.array(code, v)
        if not _LITTLE:
            a = array.array(code, a)
            a.byteswap()
        return Tag(tag, a.tobytes())
    return pack


def _as_bytes(v):
    return v if type(v) is bytes else bytes(v)


def _cbor_converter(defs: Definitions, msgdef: MsgDef):
    """A function msg -> CBOR-ready msg, or None when the message needs no change."""
    def make(msgdef: MsgDef):
        actions = []
        for f in msgdef.fields:
            if f.array is not None and (f.type in B64_TYPES or f.type == 'byte'):
                actions.append((f.name, _as_bytes))
            elif f.array is not None and f.type in CBOR_TAGS:
                actions.append((f.name, _packer(f.type)))
            elif not f.primitive:
                sub = _cbor_converter(defs, defs.msg(f.type))
                if sub is not None:
                    actions.append((f.name, sub if f.array is None else (lambda v, s=sub: [s(x) for x in v])))
        if not actions:
            return None
        actions = tuple(actions)

        def convert(m: dict) -> dict:
            out = dict(m)
            for name, fn in actions:
                v = m.get(name)
                if v is not None:
                    out[name] = fn(v)
            return out
        return convert
    return compiled(defs, 'cbor', msgdef, make)


def to_cbor(msgdef: MsgDef, msg: dict, defs: Definitions) -> dict:
    """The message with numeric arrays as typed-array tags and byte arrays as byte strings."""
    convert = _cbor_converter(defs, msgdef)
    return msg if convert is None else convert(msg)
