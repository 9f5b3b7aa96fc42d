"""Per-type work compiled once: caches keyed by Definitions, and message defaults.

Conversions build closures per message type the first time they meet it; later messages walk
those precomputed field tables instead of interpreting the definition again.
"""

from __future__ import annotations

import weakref

from .msgdefs import Definitions, Field, MsgDef, scalar_default

B64_TYPES = frozenset({'uint8', 'char'})  # uint8[]/char[] are base64 in JSON; byte[] is a list (as rclpy)
# non-zero defaults declared in .msg files that the rosbags typestore does not carry
FIELD_DEFAULTS = {('geometry_msgs/msg/Quaternion', 'w'): 1.0}
MISSING = object()

_TABLES: weakref.WeakKeyDictionary[Definitions, dict[str, dict]] = weakref.WeakKeyDictionary()


def table(defs: Definitions, kind: str) -> dict:
    """The cache of one kind of compiled function for these definitions (dies with them)."""
    tables = _TABLES.get(defs)
    if tables is None:
        tables = _TABLES[defs] = {}
    found = tables.get(kind)
    if found is None:
        found = tables[kind] = {}
    return found


def compiled(defs: Definitions, kind: str, msgdef: MsgDef, make):
    """make(msgdef), cached by type name; recompiled if another MsgDef object has that name."""
    cache = table(defs, kind)
    hit = cache.get(msgdef.type)
    if hit is not None and hit[0] is msgdef:
        return hit[1]
    fn = make(msgdef)
    cache[msgdef.type] = (msgdef, fn)
    return fn




def field_default(defs: Definitions, f: Field, owner: str = ''):
    """(constant, factory) for a field of message type owner; factory is None when immutable.
    A default its definition gives (``float64 x 1.5``, ``int32[] a [1, 2]``) comes first."""
    if f.default is not None:
        if f.array is None:
            return f.default, None
        if f.type in B64_TYPES:
            return bytes(f.default), None
        given = f.default
        return None, lambda: list(given)
    if f.array is None:
        if f.primitive:
            return FIELD_DEFAULTS.get((owner, f.name), scalar_default(f)), None
        return None, default_factory(defs, defs.msg(f.type))
    n = f.array
    if f.type in B64_TYPES:
        return bytes(n), None
    if f.primitive:
        if n == 0:
            return None, list
        item = scalar_default(f)
        return None, lambda: [item] * n
    sub = default_factory(defs, defs.msg(f.type))
    return None, lambda: [sub() for _ in range(n)]


def default_factory(defs: Definitions, msgdef: MsgDef):
    def make(msgdef: MsgDef):
        items = tuple((f.name, *field_default(defs, f, msgdef.type)) for f in msgdef.fields)

        def default() -> dict:
            return {name: const if factory is None else factory() for name, const, factory in items}
        return default
    return compiled(defs, 'default', msgdef, make)


def default_message(defs: Definitions, msgdef: MsgDef) -> dict:
    """A message of msgdef's type with every field at its default (fresh containers each call)."""
    return default_factory(defs, msgdef)()
