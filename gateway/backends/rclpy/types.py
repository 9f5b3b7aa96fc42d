"""ROS 2 interfaces as rclpy sees them: generated classes, MsgDefs from introspection, dict <-> message.

Imports no ROS module at import time: the generated classes are imported by name when a type is
first used (``importlib`` on ``pkg.msg`` / ``pkg.srv`` / ``pkg.action``, as
``rosidl_runtime_py.utilities`` does). Dicts follow ``protocol.convert.from_json``'s shape:
uint8[]/char[]/byte[] as ``bytes``, other arrays as lists, nested messages as dicts.
"""

from __future__ import annotations

import array
import importlib
import os
import re
import sys
from pathlib import Path
from typing import Any

from protocol.msgdefs import (
    INTERFACES_DIR, ActionDef, Definitions, Field, MsgDef, SrvDef, UnknownType, normalize, parse_msg,
)

from . import cdr as rclpy_cdr
from .rawtype import is_raw

# IDL names (as get_fields_and_field_types() reports them) -> .msg primitive names
IDL_PRIMITIVES = {
    'double': 'float64', 'float': 'float32', 'boolean': 'bool', 'octet': 'byte', 'char': 'char',
    'wchar': 'char', 'long double': 'float64',
    **{t: t for t in ('int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64',
                      'float32', 'float64', 'string', 'wstring', 'bool', 'byte')},
}
# array.array type codes rosidl_generator_py uses for numeric sequences (numpy dtypes alike)
TYPECODES = {
    'float32': 'f', 'float64': 'd', 'int8': 'b', 'uint8': 'B', 'int16': 'h', 'uint16': 'H',
    'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q',
}
KINDS = ('msg', 'srv', 'action')
# the names rosidl_generator_py gives an action's derived types inside its class's Impl
DERIVED_IMPL = {'SendGoal': 'SendGoalService', 'GetResult': 'GetResultService', 'FeedbackMessage': 'FeedbackMessage'}
# Jazzy's generated classes write 'string<22>'; 'string<=22' (the .msg spelling) is accepted too
BOUNDED_STRING = re.compile(r'^(w?string)<=?(\d+)>?$')


def parse_idl_type(name: str, idl: str) -> Field:
    """One entry of get_fields_and_field_types(): 'sequence<float, 5>', 'double[9]', 'string<10>',
    'geometry_msgs/Vector3' -> a Field in protocol.msgdefs terms."""
    array_len: int | None = None
    bound = 0
    text = idl.strip()
    if text.startswith('sequence<') and text.endswith('>'):
        inner = text[len('sequence<'):-1]
        elem, sep, size = inner.rpartition(',')
        if sep and size.strip().isdigit():
            inner, bound = elem, int(size)
        text, array_len = inner.strip(), 0
    elif text.endswith(']') and '[' in text:
        text, _, size = text[:-1].rpartition('[')
        array_len = int(size)
    string_bound = 0
    bounded = BOUNDED_STRING.match(text)
    if bounded:
        text, string_bound = bounded[1], int(bounded[2])
    if '/' in text:
        base = normalize(text, 'msg')
    else:
        try:
            base = IDL_PRIMITIVES[text]
        except KeyError:
            raise UnknownType(f'field {name!r} has an unsupported type {idl!r}') from None
    return Field(name, base, array_len, bound, string_bound)


def constants_of(cls) -> tuple[tuple[str, str, object], ...]:
    """Constants a generated class carries (its metaclass keeps them in a name-mangled dict)."""
    meta = type(cls)
    consts = getattr(meta, f'_{meta.__name__}__constants', None) or {}
    out = []
    for key, value in consts.items():
        if isinstance(value, bool):
            type_ = 'bool'
        elif isinstance(value, int):
            type_ = 'int64' if not -(2**31) <= value < 2**31 else 'int32'
        elif isinstance(value, float):
            type_ = 'float64'
        elif isinstance(value, str):
            type_ = 'string'
        elif isinstance(value, bytes) and len(value) == 1:
            type_, value = 'byte', value[0]
        else:
            continue  # array defaults of fields, not constants
        out.append((key, type_, value))
    return tuple(out)


def import_type(full: str, kind: str):
    """'pkg/kind/Name' -> the generated Python class; UnknownType when it is not installed."""
    pkg, _, name = normalize(full, kind).split('/')
    try:
        module = importlib.import_module(f'{pkg}.{kind}')
    except ImportError:
        raise UnknownType(f'{full}: package {pkg!r} has no installed {kind} interfaces '
                          f'(is it built and sourced?)') from None
    cls = getattr(module, name, None)
    needed = {'msg': 'get_fields_and_field_types', 'srv': 'Request', 'action': 'Goal'}[kind]
    if cls is None or not hasattr(cls, needed):
        raise UnknownType(f'{full}: no {kind} type {name!r} in package {pkg!r}')
    return cls


# the parts of a service's and an action's definition, in the order SrvDef and ActionDef take them
PARTS = {'srv': ('Request', 'Response'), 'action': ('Goal', 'Result', 'Feedback')}


class RosDefinitions(Definitions):
    """Definitions resolved on demand from the installed generated classes, and (once the backend
    has a node) message types the install lacks from the graph (``graph``: graphtypes.GraphTypes)."""

    def __init__(self, text_dirs: tuple[Path, ...] = ()) -> None:
        """text_dirs: where ``<pkg>/<kind>/<Name>.<kind>`` texts of services and actions the
        install lacks are found (the operator's first, then the ones rosgate ships)."""
        super().__init__()
        self._classes: dict[str, Any] = {}
        self.graph = None
        self.text_dirs = (*map(Path, text_dirs), INTERFACES_DIR)
        self.described: dict[str, str] = {}     # message types known from the graph -> .msg text
        self.unbuilt: set[str] = set()          # srv/action types known from texts, not installed

    def msg(self, name: str) -> MsgDef:
        try:
            return super().msg(name)
        except UnknownType:
            pass
        parts = name.strip('/').split('/')
        if len(parts) == 3 and parts[1] in ('srv', 'action') and '_' in parts[2]:
            whole = f'{parts[0]}/{parts[1]}/{parts[2].rpartition("_")[0]}'
            getattr(self, parts[1])(whole)
            return super().msg(name)
        full = normalize(name, 'msg')
        try:
            cls = self.msg_class(full)
        except UnknownType:
            if self.graph is None:
                raise
            self._add_described(full)
            return self._msgs[full]
        self._add(full, cls)
        return self._msgs[full]

    def _add_described(self, full: str) -> None:
        """A type the install lacks, with every type it references, from the graph's texts."""
        texts = self.graph.describe(full).texts
        new = []
        for name, text in texts.items():
            if name in self._msgs or (name != full and _installed(name)):
                continue
            self._msgs[name] = parse_msg(name, text)
            self.described[name] = text
            new.append(self._msgs[name])
        for msgdef in new:     # installed types it references resolve as usual
            for f in msgdef.fields:
                if not f.primitive:
                    self.msg(f.type)

    def srv(self, name: str) -> SrvDef:
        return self._interface(name, 'srv', super().srv)

    def action(self, name: str) -> ActionDef:
        return self._interface(name, 'action', super().action)

    def _interface(self, name: str, kind: str, known):
        """A service or action: known already (``known``), else from its installed classes, else
        from its text."""
        try:
            return known(name)
        except UnknownType:
            full = normalize(name, kind)
        try:
            cls = getattr(self, f'{kind}_class')(full)
        except UnknownType:
            return self._from_text(full, kind)
        make = SrvDef if kind == 'srv' else ActionDef
        whole = make(full, *(self._part(f'{full}_{part}', getattr(cls, part)) for part in PARTS[kind]))
        (self._srvs if kind == 'srv' else self._actions)[full] = whole
        return whole

    def text(self, full: str, kind: str) -> str | None:
        """The text of an interface from the text directories, or None."""
        pkg, _, name = full.split('/')
        for root in self.text_dirs:
            path = Path(root, pkg, kind, f'{name}.{kind}')
            if path.is_file():
                return path.read_text()
        return None

    def _from_text(self, full: str, kind: str):
        """A service or action the install lacks, from its text (rosgate's, or the operator's
        --interfaces directory); the messages it uses resolve as usual (installed, or the graph).
        Calling it needs its package built (``build.Builder``)."""
        text = self.text(full, kind)
        if text is None:
            raise UnknownType(
                f'unknown {kind} type {full!r}: it is not installed here, no {kind} text of it is in '
                f'{", ".join(map(str, self.text_dirs))}, and the ROS graph cannot describe '
                f'{"services" if kind == "srv" else "actions"}: install its package, or name a '
                f'directory holding <pkg>/{kind}/<Name>.{kind} with --interfaces')
        whole = getattr(Definitions(), f'add_{kind}')(full, text)
        for part in (whole.request, whole.response) if kind == 'srv' else (whole.goal, whole.result, whole.feedback):
            for f in part.fields:
                if not f.primitive:
                    self.msg(f.type)
        (self._srvs if kind == 'srv' else self._actions)[full] = whole
        self.unbuilt.add(full)
        return whole

    def forget_classes(self, pkg: str) -> None:
        """A package was built and loaded: its types take the generated classes from now on."""
        for full in [f for f in self._classes if f.startswith(pkg + '/')]:
            del self._classes[full]
        self.unbuilt = {f for f in self.unbuilt if not f.startswith(pkg + '/')}

    def interfaces(self) -> list[str]:
        return sorted({*installed_interfaces(), *self.described})

    # classes
    def msg_class(self, full: str):
        found = self._derived_class(full)
        if found is not None:
            return found
        full = normalize(full, 'msg')
        try:
            return self._class(full, 'msg')
        except UnknownType:
            # the fields of X_SendGoal, X_GetResult, X_FeedbackMessage name X's parts 'pkg/X_Goal'
            pkg, _, name = full.split('/')
            base, _, part = name.rpartition('_')
            if not base or part not in ('Goal', 'Result', 'Feedback'):
                raise
            return getattr(self.action_class(f'{pkg}/action/{base}'), part)

    def srv_class(self, full: str):
        return self._derived_class(full) or self._class(normalize(full, 'srv'), 'srv')

    def _derived_class(self, full: str):
        """The class rosidl generates for an action's X_SendGoal, X_GetResult or X_FeedbackMessage
        (in the action class's ``Impl``), or None for any other name."""
        if self.derived(full) is None:
            return None
        whole, _, part = full.rpartition('_')
        return getattr(self.action_class(whole).Impl, DERIVED_IMPL[part])

    def action_class(self, full: str):
        return self._class(normalize(full, 'action'), 'action')

    def _class(self, full: str, kind: str):
        cls = self._classes.get(full)
        if cls is None:
            try:
                cls = import_type(full, kind)
            except UnknownType:
                if full not in self.described:
                    raise
                cls = self.graph.type_support(full)     # CDR only: see rawtype
            self._classes[full] = cls
        return cls

    def _part(self, name: str, cls) -> MsgDef:
        msgdef = msgdef_of(name, cls)
        for f in msgdef.fields:
            if not f.primitive:
                self.msg(f.type)
        return msgdef

    def _add(self, full: str, cls) -> None:
        self._msgs[full] = msgdef = msgdef_of(full, cls)
        for f in msgdef.fields:
            if not f.primitive and f.type not in self._msgs:
                self.msg(f.type)


def _installed(full: str) -> bool:
    try:
        import_type(full, 'msg')
    except UnknownType:
        return False
    return True


def msgdef_of(name: str, cls) -> MsgDef:
    fields = tuple(parse_idl_type(n, t) for n, t in cls.get_fields_and_field_types().items())
    return MsgDef(name, fields, constants_of(cls))


def installed_interfaces() -> list[str]:
    """Every interface in the ament index ('pkg/msg/Name', ...), as `ros2 interface list` shows."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p] or [sys.prefix]
    names: set[str] = set()
    for prefix in prefixes:
        index = Path(prefix, 'share', 'ament_index', 'resource_index', 'rosidl_interfaces')
        if not index.is_dir():
            continue
        for marker in index.iterdir():
            for line in marker.read_text().splitlines():
                kind, _, file = line.strip().partition('/')
                stem, dot, ext = file.rpartition('.')
                if kind in KINDS and dot and ext in ('idl', kind):
                    names.add(f'{marker.name}/{kind}/{stem}')
    return sorted(names)


# --- message <-> dict -------------------------------------------------------------------------

class Converter:
    """Converts between generated message objects and rosbridge-shaped dicts, per class."""

    def __init__(self, defs: RosDefinitions):
        self._defs = defs
        self._plans: dict[type, tuple] = {}

    def _plan(self, cls) -> tuple:
        plan = self._plans.get(cls)
        if plan is None:
            entries = []
            for name, idl in cls.get_fields_and_field_types().items():
                f = parse_idl_type(name, idl)
                sub = None if f.primitive else self._defs.msg_class(f.type)
                entries.append((name, f, sub))
            plan = self._plans[cls] = tuple(entries)
        return plan

    def to_dict(self, msg) -> dict:
        out = {}
        for name, f, sub in self._plan(type(msg)):
            value = getattr(msg, name)
            if sub is not None:
                out[name] = self.to_dict(value) if f.array is None else [self.to_dict(v) for v in value]
            elif f.array is None:
                out[name] = scalar_out(f.type, value)
            elif f.is_bytes:
                out[name] = bytes_out(value)
            elif f.type in ('byte', 'char'):
                out[name] = [scalar_out(f.type, v) for v in value]
            else:
                out[name] = value.tolist() if hasattr(value, 'tolist') else list(value)
        return out

    def cdr_reader(self, cls):
        """CDR bytes -> the dict to_dict makes (raising rclpy_cdr.Slow where it cannot), or None.
        For a type described by the graph (no class): the whole decoder."""
        if is_raw(cls):
            return self._defs.graph.reader(cls.raw_type.type)
        return rclpy_cdr.reader(self._plan, cls)

    def cdr_writer(self, cls):
        """A dict -> the CDR bytes rclpy would publish for from_dict(cls, dict) (raising
        rclpy_cdr.Slow for a dict it leaves to from_dict), or None. For a type described by the
        graph (no class): the whole encoder (raising ConversionError for bad values)."""
        if is_raw(cls):
            return self._defs.graph.writer(cls.raw_type.type)
        return rclpy_cdr.writer(self._plan, cls)

    def from_dict(self, cls, data: dict):
        msg = cls()
        for name, f, sub in self._plan(cls):
            if name not in data:
                continue  # the class default
            value = data[name]
            if sub is not None:
                value = (self.from_dict(sub, value) if f.array is None
                         else [self.from_dict(sub, v) for v in value])
            elif f.array is None:
                value = scalar_in(f.type, value)
            else:
                value = array_in(f, value)
            setattr(msg, name, value)
        return msg


def scalar_out(type_: str, value):
    if type_ == 'byte' and isinstance(value, (bytes, bytearray)):
        return value[0] if value else 0
    if type_ == 'char' and isinstance(value, str):
        return ord(value) if value else 0
    return value


def scalar_in(type_: str, value):
    if type_ == 'byte':
        return bytes((value,))
    if type_ == 'char':
        return chr(value)
    if type_ in ('float32', 'float64'):
        return float(value)
    return value


def bytes_out(value) -> bytes:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    if hasattr(value, 'tobytes'):            # array.array('B') or a numpy uint8 array
        return value.tobytes()
    items = list(value)
    if items and isinstance(items[0], (bytes, bytearray)):   # octet sequences: 1-byte bytes
        return b''.join(items)
    if items and isinstance(items[0], str):
        return ''.join(items).encode('latin-1')
    return bytes(items)


def array_in(f: Field, value):
    if f.type == 'byte':
        return [bytes((b,)) for b in value]
    if f.type == 'char':
        return [chr(b) for b in value]
    code = TYPECODES.get(f.type)
    if code is None:
        return list(value)                   # bool and string arrays
    if f.array:                              # fixed size: numpy, as the generated setter wants
        import numpy  # noqa: PLC0415 (a dependency of every generated message package)
        return numpy.array(list(value) if isinstance(value, (bytes, bytearray)) else value,
                           dtype=numpy.dtype(code))
    return array.array(code, value)
