"""Message values: JSON rules (validate, fill defaults), CBOR typed arrays and CDR, driven by msgdefs.

Per message type the work is compiled once into closures (cached per Definitions), so converting
a message is a walk over precomputed field tables, not an interpretation of its definition.
"""

from __future__ import annotations

import array
import binascii
import math
import sys
import weakref

import cbor2

from .errors import ConversionError, json_type
from .msgdefs import FLOATS, INTEGERS, Definitions, Field, MsgDef

NAN = math.nan
F32_MAX = 3.4028234663852886e38
TIME_TYPES = frozenset({'builtin_interfaces/msg/Time', 'builtin_interfaces/msg/Duration'})
TIME_ALIASES = {'secs': 'sec', 'nsecs': 'nanosec'}
B64_TYPES = frozenset({'uint8', 'char'})  # uint8[]/char[] are base64 in JSON; byte[] is a list (as rclpy)
# RFC 8746 little-endian typed-array tag, array.array typecode and numpy dtype per element type
CBOR_TAGS = {'float64': (86, 'd', '<f8'), 'float32': (85, 'f', '<f4'), 'int8': (72, 'b', 'i1'),
             'int16': (77, 'h', '<i2'), 'uint16': (69, 'H', '<u2'), 'int32': (78, 'i', '<i4'),
             'uint32': (70, 'I', '<u4'), 'int64': (79, 'q', '<i8'), 'uint64': (71, 'Q', '<u8')}
# non-zero defaults declared in .msg files that the rosbags typestore does not carry
FIELD_DEFAULTS = {('geometry_msgs/msg/Quaternion', 'w'): 1.0}
_LITTLE = sys.byteorder == 'little'
_MISSING = object()
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


def _got(v) -> str:
    return json_type(v)


# --- compiled per Definitions -------------------------------------------------------------------

class _Cache:
    __slots__ = ('json', 'default', 'cbor', 'cdr_build', 'cdr_read', 'cdr_types')

    def __init__(self) -> None:
        self.json: dict = {}
        self.default: dict = {}
        self.cbor: dict = {}
        self.cdr_build: dict = {}
        self.cdr_read: dict = {}
        self.cdr_types: dict = {}


_CACHES: weakref.WeakKeyDictionary[Definitions, _Cache] = weakref.WeakKeyDictionary()


def _cache(defs: Definitions) -> _Cache:
    cache = _CACHES.get(defs)
    if cache is None:
        cache = _CACHES[defs] = _Cache()
    return cache


def _compiled(table: dict, msgdef: MsgDef, make):
    """table[type] -> (msgdef, fn); recompiled when a different MsgDef object shares the name."""
    hit = table.get(msgdef.type)
    if hit is not None and hit[0] is msgdef:
        return hit[1]
    fn = make(msgdef)
    table[msgdef.type] = (msgdef, fn)
    return fn


# --- defaults -----------------------------------------------------------------------------------

def _scalar_default(f: Field):
    if f.type in FLOATS:
        return 0.0
    if f.type == 'bool':
        return False
    if f.type in ('string', 'wstring'):
        return ''
    return 0


def _field_default(defs: Definitions, f: Field, owner: str = ''):
    """(constant, factory): factory is None for immutable defaults."""
    if f.array is None:
        if f.primitive:
            return FIELD_DEFAULTS.get((owner, f.name), _scalar_default(f)), None
        return None, _default_factory(defs, defs.msg(f.type))
    n = f.array
    if f.type in B64_TYPES:
        return bytes(n), None
    if f.primitive:
        if n == 0:
            return None, list
        item = _scalar_default(f)
        return None, lambda: [item] * n
    sub = _default_factory(defs, defs.msg(f.type))
    return None, lambda: [sub() for _ in range(n)]


def _default_factory(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        items = tuple((f.name, *_field_default(defs, f, msgdef.type)) for f in msgdef.fields)

        def default() -> dict:
            return {name: const if factory is None else factory() for name, const, factory in items}
        return default
    return _compiled(_cache(defs).default, msgdef, make)


def default_message(defs: Definitions, msgdef: MsgDef) -> dict:
    """A message of msgdef's type with every field at its default."""
    return _default_factory(defs, msgdef)()


# --- JSON in: validate and fill defaults --------------------------------------------------------

def _float64(v):
    t = type(v)
    if t is float:
        return v
    if t is int:
        try:
            return float(v)
        except OverflowError:
            raise _Bad(f'is out of range for float64, got {v}') from None
    if v is None:
        return NAN
    raise _Bad(f'must be a number, got {_got(v)}')


def _float32(v):
    x = _float64(v)
    if -F32_MAX <= x <= F32_MAX or x != x or math.isinf(x):
        return x
    raise _Bad(f'is out of range for float32, got {v}')


def _boolean(v):
    if type(v) is bool:
        return v
    raise _Bad(f'must be a boolean, got {_got(v)}')


def _integer(typ: str):
    lo, hi = INTEGERS[typ]
    article = 'an' if typ.startswith('int') else 'a'

    def check(v):
        if type(v) is int:
            if lo <= v <= hi:
                return v
            raise _Bad(f'must be {article} {typ} ({lo}..{hi}), got {v}')
        raise _Bad(f'must be an integer, got {_got(v)}')
    return check


def _string(bound: int):
    def check(v):
        if type(v) is str:
            if bound and len(v) > bound:
                raise _Bad(f'must be at most {bound} characters, got {len(v)}')
            return v
        raise _Bad(f'must be a string, got {_got(v)}')
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


def _first_bad(values, item_check):
    """Re-check items one by one to name the failing index (error path only)."""
    for i, x in enumerate(values):
        try:
            item_check(x)
        except _Bad as e:
            e.parts.append(i)
            raise
    raise _Bad('has an invalid element')


def _as_list(v) -> list:
    if type(v) is list:
        return v
    if type(v) is tuple:
        return list(v)
    raise _Bad(f'must be an array, got {_got(v)}')


def _bytes_check(f: Field, as_list: bool):
    """uint8[]/char[] -> bytes (from base64, a byte string or a list of ints); byte[] -> list of ints."""
    length = _length_check(f)
    what = 'must be a base64 string or an array of integers 0..255'

    def check(v):
        t = type(v)
        if t is str:
            try:
                b = binascii.a2b_base64(v, strict_mode=True)
            except binascii.Error as e:
                raise _Bad(f'{what}, got a string that is not base64 ({e})') from None
        elif t is bytes:
            b = v
        elif t is list or t is tuple or t is bytearray or t is memoryview:
            try:
                b = bytes(v)
            except (ValueError, TypeError):
                _first_bad(v, _integer('uint8'))
                raise
        else:
            raise _Bad(f'{what}, got {_got(v)}')
        if length is not None:
            length(b)
        return list(b) if as_list else b
    return check


def _array_check(defs: Definitions, f: Field):
    if f.type in B64_TYPES:
        return _bytes_check(f, as_list=False)
    if f.type == 'byte':
        return _bytes_check(f, as_list=True)
    length = _length_check(f)
    if not f.primitive:
        sub = _json_converter(defs, defs.msg(f.type))

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            try:
                return [sub(x) for x in v]
            except _Bad:
                _first_bad(v, sub)
                raise
        return check

    item = _scalar_check(f)
    if f.type in FLOATS:
        f32 = f.type == 'float32'

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            types = set(map(type, v))
            if types <= _FLOAT_OK and not f32:
                return v
            if types <= _NUMBER_OK:
                try:
                    out = [NAN if x is None else float(x) for x in v]
                except OverflowError:
                    out = None
                if out is not None and (not f32 or all(-F32_MAX <= x <= F32_MAX or x != x or math.isinf(x)
                                                        for x in out)):
                    return out
            _first_bad(v, item)
        return check

    if f.type in INTEGERS:
        lo, hi = INTEGERS[f.type]

        def check(v):
            v = _as_list(v)
            if length is not None:
                length(v)
            if set(map(type, v)) <= _INT_OK and (not v or (lo <= min(v) and max(v) <= hi)):
                return v
            _first_bad(v, item)
        return check

    ok = _BOOL_OK if f.type == 'bool' else _STR_OK
    bound = f.string_bound

    def check(v):
        v = _as_list(v)
        if length is not None:
            length(v)
        if set(map(type, v)) <= ok and not (bound and v and max(map(len, v)) > bound):
            return v
        _first_bad(v, item)
    return check


def _field_check(defs: Definitions, f: Field):
    if f.array is not None:
        return _array_check(defs, f)
    if f.primitive:
        return _scalar_check(f)
    return _json_converter(defs, defs.msg(f.type))


def _json_converter(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        fields = tuple((f.name, _field_check(defs, f), *_field_default(defs, f, msgdef.type)) for f in msgdef.fields)
        names = frozenset(f.name for f in msgdef.fields)
        typename = msgdef.type

        def convert(v):
            if type(v) is not dict:
                raise _Bad(f'must be an object, got {_got(v)}')
            out = {}
            seen = 0
            for name, check, const, factory in fields:
                x = v.get(name, _MISSING)
                if x is _MISSING:
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

            def convert(v):  # noqa: F811 (Time/Duration also accept ROS 1 secs/nsecs)
                if type(v) is dict and ('secs' in v or 'nsecs' in v):
                    v = {TIME_ALIASES.get(k, k): x for k, x in v.items()}
                return plain(v)
        return convert
    return _compiled(_cache(defs).json, msgdef, make)


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
        args = dict(zip(names, args))
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
    return _compiled(_cache(defs).cbor, msgdef, make)


def to_cbor(msgdef: MsgDef, msg: dict, defs: Definitions) -> dict:
    """The message with numeric arrays as typed-array tags and byte arrays as byte strings."""
    convert = _cbor_converter(defs, msgdef)
    return msg if convert is None else convert(msg)


# --- CDR (cbor-raw, rclpy) through rosbags ------------------------------------------------------

def _pyname(name: str) -> str:
    import keyword  # noqa: PLC0415

    return f'{name}_' if keyword.iskeyword(name) else name


def _cdr_array(f: Field):
    import numpy as np  # noqa: PLC0415 (a rosbags dependency; only needed for CDR)

    if f.type in B64_TYPES:
        return lambda v: np.frombuffer(v, np.uint8) if type(v) is bytes else np.asarray(v, np.uint8)
    dtype = {'byte': np.uint8, 'bool': np.bool_, 'float32': np.float32}.get(f.type) or np.dtype(f.type)
    if f.type == 'float32':
        def to_f32(v):
            with np.errstate(over='ignore'):
                return np.asarray(v, np.float64).astype(np.float32)
        return to_f32
    return lambda v: np.asarray(v, dtype)


def _cdr_builder(defs: Definitions, msgdef: MsgDef):
    typestore = defs.typestore

    def make(msgdef: MsgDef):
        cls = typestore.types[msgdef.type]
        fields = []
        for f in msgdef.fields:
            fn = None
            if f.array is None and not f.primitive:
                fn = _cdr_builder(defs, defs.msg(f.type))
            elif f.array is None and f.type == 'byte':
                fn = lambda v: v - 256 if v > 127 else v  # noqa: E731 (rosbags packs byte as int8)
            elif f.array is not None and not f.primitive:
                sub = _cdr_builder(defs, defs.msg(f.type))
                fn = lambda v, s=sub: [s(x) for x in v]  # noqa: E731
            elif f.array is not None and f.type not in ('string', 'wstring'):
                fn = _cdr_array(f)
            fields.append((f.name, _pyname(f.name), fn, *_field_default(defs, f, msgdef.type)))
        fields = tuple(fields)

        def build(m: dict):
            kw = {}
            for name, pyname, fn, const, factory in fields:
                v = m.get(name, _MISSING)
                if v is _MISSING:
                    v = const if factory is None else factory()
                kw[pyname] = v if fn is None else fn(v)
            return cls(**kw)
        return build
    return _compiled(_cache(defs).cdr_build, msgdef, make)


def _cdr_reader(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        fields = []
        for f in msgdef.fields:
            fn = None
            if f.array is None and not f.primitive:
                fn = _cdr_reader(defs, defs.msg(f.type))
            elif f.array is None and f.type == 'byte':
                fn = lambda v: v & 0xFF  # noqa: E731
            elif f.array is not None and not f.primitive:
                sub = _cdr_reader(defs, defs.msg(f.type))
                fn = lambda v, s=sub: [s(x) for x in v]  # noqa: E731
            elif f.array is not None and f.type in B64_TYPES:
                fn = lambda v: v.tobytes()  # noqa: E731
            elif f.array is not None and f.type == 'byte':
                fn = lambda v: v.view('u1').tolist()  # noqa: E731
            elif f.array is not None and f.type in ('string', 'wstring'):
                fn = list
            elif f.array is not None:
                fn = lambda v: v.tolist()  # noqa: E731
            fields.append((f.name, _pyname(f.name), fn))
        fields = tuple(fields)

        def read(o) -> dict:
            out = {}
            for name, pyname, fn in fields:
                v = getattr(o, pyname)
                out[name] = v if fn is None else fn(v)
            return out
        return read
    return _compiled(_cache(defs).cdr_read, msgdef, make)


def _cdr_type(defs: Definitions, type: str) -> MsgDef:  # noqa: A002
    cache = _cache(defs).cdr_types
    msgdef = cache.get(type)
    if msgdef is None:
        if defs.typestore is None:
            raise ConversionError('CDR needs definitions loaded from a rosbags typestore')
        msgdef = cache[type] = defs.msg(type)
        if msgdef.type not in defs.typestore.types:
            raise ConversionError(f'{msgdef.type} is not registered with the CDR typestore')
    return msgdef


def to_cdr(defs: Definitions, type: str, msg: dict) -> bytes:  # noqa: A002
    """CDR bytes (with encapsulation header) of a message dict, as ROS 2 puts on the wire."""
    msgdef = _cdr_type(defs, type)
    try:
        obj = _cdr_builder(defs, msgdef)(msg)
        return bytes(defs.typestore.serialize_cdr(obj, msgdef.type))
    except Exception as e:  # bad values surface as rosbags SerdeError, struct.error, numpy errors
        raise ConversionError(f'cannot serialize {msgdef.type}: {e}') from None


def from_cdr(defs: Definitions, type: str, data: bytes) -> dict:  # noqa: A002
    """A message dict (uint8[] as bytes, other arrays as lists) from CDR bytes."""
    msgdef = _cdr_type(defs, type)
    try:
        obj = defs.typestore.deserialize_cdr(data, msgdef.type)
    except Exception as e:  # rosbags SerdeError and friends
        raise ConversionError(f'cannot deserialize {msgdef.type}: {e}') from None
    return _cdr_reader(defs, msgdef)(obj)
