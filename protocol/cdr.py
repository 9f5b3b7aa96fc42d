"""CDR, the ROS 2 wire format (cbor-raw subscriptions, the rclpy backend), through rosbags.

Message dicts map to rosbags message objects and back with per-type builders; numeric arrays
become numpy arrays on the way in and lists (uint8[]/char[]: bytes) on the way out.
"""

from __future__ import annotations

import keyword

from .compiled import B64_TYPES, MISSING, compiled, field_default, table
from .errors import ConversionError
from .msgdefs import Definitions, Field, MsgDef


def _pyname(name: str) -> str:
    """rosbags' attribute name for a field (Python keywords get a trailing underscore)."""
    return f'{name}_' if keyword.iskeyword(name) else name


def _cdr_array(f: Field):
    import numpy as np  # a rosbags dependency; only needed for CDR

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
                fn = lambda v: v - 256 if v > 127 else v  # rosbags packs byte as int8
            elif f.array is not None and not f.primitive:
                sub = _cdr_builder(defs, defs.msg(f.type))
                fn = lambda v, s=sub: [s(x) for x in v]
            elif f.array is not None and f.type not in ('string', 'wstring'):
                fn = _cdr_array(f)
            fields.append((f.name, _pyname(f.name), fn, *field_default(defs, f, msgdef.type)))
        fields = tuple(fields)

        def build(m: dict):
            kw = {}
            for name, pyname, fn, const, factory in fields:
                v = m.get(name, MISSING)
                if v is MISSING:
                    v = const if factory is None else factory()
                kw[pyname] = v if fn is None else fn(v)
            return cls(**kw)
        return build
    return compiled(defs, 'cdr_build', msgdef, make)


def _cdr_reader(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        fields = []
        for f in msgdef.fields:
            fn = None
            if f.array is None and not f.primitive:
                fn = _cdr_reader(defs, defs.msg(f.type))
            elif f.array is None and f.type == 'byte':
                fn = lambda v: v & 0xFF
            elif f.array is not None and not f.primitive:
                sub = _cdr_reader(defs, defs.msg(f.type))
                fn = lambda v, s=sub: [s(x) for x in v]
            elif f.array is not None and f.type in B64_TYPES:
                fn = lambda v: v.tobytes()
            elif f.array is not None and f.type == 'byte':
                fn = lambda v: v.view('u1').tolist()
            elif f.array is not None and f.type in ('string', 'wstring'):
                fn = list
            elif f.array is not None:
                fn = lambda v: v.tolist()
            fields.append((f.name, _pyname(f.name), fn))
        fields = tuple(fields)

        def read(o) -> dict:
            out = {}
            for name, pyname, fn in fields:
                v = getattr(o, pyname)
                out[name] = v if fn is None else fn(v)
            return out
        return read
    return compiled(defs, 'cdr_read', msgdef, make)


def _cdr_type(defs: Definitions, type: str) -> MsgDef:
    cache = table(defs, 'cdr_type')
    msgdef = cache.get(type)
    if msgdef is None:
        if defs.typestore is None:
            raise ConversionError('CDR needs definitions loaded from a rosbags typestore')
        msgdef = defs.msg(type)
        if msgdef.type not in defs.typestore.types:
            raise ConversionError(f'{msgdef.type} is not registered with the CDR typestore')
        cache[type] = msgdef
    return msgdef


def to_cdr(defs: Definitions, type: str, msg: dict) -> bytes:
    """CDR bytes (with encapsulation header) of a message dict, as ROS 2 puts on the wire."""
    msgdef = _cdr_type(defs, type)
    try:
        obj = _cdr_builder(defs, msgdef)(msg)
        return bytes(defs.typestore.serialize_cdr(obj, msgdef.type))
    except Exception as e:  # bad values surface as rosbags SerdeError, struct.error, numpy errors
        raise ConversionError(f'cannot serialize {msgdef.type}: {e}') from None


def from_cdr(defs: Definitions, type: str, data: bytes) -> dict:
    """A message dict (uint8[] as bytes, other arrays as lists) from CDR bytes."""
    msgdef = _cdr_type(defs, type)
    try:
        obj = defs.typestore.deserialize_cdr(data, msgdef.type)
    except Exception as e:  # rosbags SerdeError and friends
        raise ConversionError(f'cannot deserialize {msgdef.type}: {e}') from None
    return _cdr_reader(defs, msgdef)(obj)
