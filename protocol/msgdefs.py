"""ROS 2 interface definitions (msg, srv, action): parsed, normalised and looked up.

Message types come from rosbags' ROS 2 Jazzy typestore; the srv and action definitions it lacks
ship as text under ``protocol/interfaces/<pkg>/<kind>/<Name>.<kind>`` and go through the same
parser. Both backends describe types with these dataclasses, so conversion and rosapi are
backend-agnostic.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring',
})
INTEGERS = {
    'byte': (0, 255), 'char': (0, 255), 'uint8': (0, 255), 'int8': (-128, 127),
    'uint16': (0, 65535), 'int16': (-32768, 32767),
    'uint32': (0, 2**32 - 1), 'int32': (-(2**31), 2**31 - 1),
    'uint64': (0, 2**64 - 1), 'int64': (-(2**63), 2**63 - 1),
}
FLOATS = frozenset({'float32', 'float64'})
BYTE_TYPES = frozenset({'uint8', 'char', 'byte'})
SEPARATOR = re.compile(r'^---\s*$', re.M)
INTERFACES_DIR = Path(__file__).parent / 'interfaces'
PLACEHOLDER = 'structure_needs_at_least_one_member'
# What rosidl derives from every action X beside its goal, result and feedback: the types of an
# action server's hidden endpoints, ``X_SendGoal`` and ``X_GetResult`` (services of
# ``<name>/_action/send_goal`` and ``get_result``) and ``X_FeedbackMessage`` (``_action/feedback``).
DERIVED = ('SendGoal', 'GetResult', 'FeedbackMessage')


class UnknownType(LookupError):
    """A type name that is malformed or not known to the definitions."""


@dataclass(frozen=True, slots=True)
class Field:
    name: str
    type: str                 # a primitive name or a full message type 'pkg/msg/Name'
    array: int | None = None  # None: scalar; 0: sequence (unbounded or bounded); N > 0: fixed array
    bound: int = 0            # upper bound of a bounded sequence (0: none)
    string_bound: int = 0     # upper bound of a bounded string (0: none)
    default: object = None    # the value its definition gives it (a tuple for an array); None: none

    @property
    def primitive(self) -> bool:
        return self.type in PRIMITIVES

    @property
    def is_bytes(self) -> bool:
        """uint8[] and char[] travel as base64 in JSON and as a byte string in CBOR."""
        return self.array is not None and self.type in BYTE_TYPES


@dataclass(frozen=True, slots=True)
class MsgDef:
    type: str
    fields: tuple[Field, ...]
    constants: tuple[tuple[str, str, object], ...] = ()


@dataclass(frozen=True, slots=True)
class SrvDef:
    type: str
    request: MsgDef
    response: MsgDef


@dataclass(frozen=True, slots=True)
class ActionDef:
    type: str
    goal: MsgDef
    result: MsgDef
    feedback: MsgDef


def normalize(name: str, kind: str = 'msg') -> str:
    """'std_msgs/String' or 'std_msgs/msg/String' -> 'std_msgs/msg/String'."""
    if not isinstance(name, str):
        raise UnknownType(f'type must be a string, got {type(name).__name__}')
    parts = name.strip('/').split('/')
    if len(parts) == 2 and all(parts):
        return f'{parts[0]}/{kind}/{parts[1]}'
    if len(parts) == 3 and all(parts) and parts[1] == kind:
        return '/'.join(parts)
    raise UnknownType(f'{name!r} is not a valid {kind} type name (expected pkg/{kind}/Name or pkg/Name)')


def short_name(name: str) -> str:
    """'geometry_msgs/msg/Twist' -> 'geometry_msgs/Twist' (rosapi's TypeDef spelling)."""
    parts = name.split('/')
    return f'{parts[0]}/{parts[-1]}' if len(parts) == 3 else name


def split_sections(text: str, count: int) -> list[str]:
    sections = SEPARATOR.split(text)
    if len(sections) != count:
        raise ValueError(f'expected {count} sections separated by ---, found {len(sections)}')
    return sections


class Definitions:
    """A registry of message, service and action definitions."""

    def __init__(self) -> None:
        self._msgs: dict[str, MsgDef] = {}
        self._srvs: dict[str, SrvDef] = {}
        self._actions: dict[str, ActionDef] = {}
        self._derived: dict[str, SrvDef | MsgDef] = {}
        self._typestore = None

    # --- building ---------------------------------------------------------------------------

    @classmethod
    def jazzy(cls) -> Definitions:
        """Every message of rosbags' Jazzy typestore plus the interfaces shipped with rosgate."""
        return _jazzy_copy()

    def load_typestore(self, typestore) -> None:
        from rosbags.interfaces import Nodetype  # noqa: PLC0415 (rosbags is heavy; load once)

        def field(name, desc) -> Field:
            kind, detail = desc
            if kind == Nodetype.BASE:
                return Field(name, detail[0], string_bound=detail[1])
            if kind == Nodetype.NAME:
                return Field(name, detail)
            (elem_kind, elem), length = detail
            base = Field('', elem[0], string_bound=elem[1]) if elem_kind == Nodetype.BASE else Field('', elem)
            if kind == Nodetype.ARRAY:
                return Field(name, base.type, array=length, string_bound=base.string_bound)
            return Field(name, base.type, array=0, bound=length, string_bound=base.string_bound)

        self._typestore = typestore
        for name, (consts, fields) in typestore.fielddefs.items():
            # rosbags gives empty messages a placeholder member that ROS clients never see
            self._msgs[name] = MsgDef(name, tuple(field(n, d) for n, d in fields if n != PLACEHOLDER),
                                      tuple(consts))

    def load_dir(self, root: Path) -> None:
        """Load every ``<pkg>/<kind>/<Name>.<kind>`` under root (msg first: srv/action use them)."""
        for kind in ('msg', 'srv', 'action'):
            for path in sorted(root.glob(f'*/{kind}/*.{kind}')):
                name = f'{path.parent.parent.name}/{kind}/{path.stem}'
                getattr(self, f'add_{kind}')(name, path.read_text())

    def add_msg(self, name: str, text: str) -> MsgDef:
        name = normalize(name, 'msg')
        self._msgs[name] = parse_msg(name, text)
        return self._msgs[name]

    def add_srv(self, name: str, text: str) -> SrvDef:
        name = normalize(name, 'srv')
        req, resp = split_sections(text, 2)
        srv = SrvDef(name, parse_msg(f'{name}_Request', req), parse_msg(f'{name}_Response', resp))
        self._srvs[name] = srv
        return srv

    def add_action(self, name: str, text: str) -> ActionDef:
        name = normalize(name, 'action')
        goal, result, feedback = split_sections(text, 3)
        action = ActionDef(name, parse_msg(f'{name}_Goal', goal), parse_msg(f'{name}_Result', result),
                           parse_msg(f'{name}_Feedback', feedback))
        self._actions[name] = action
        return action

    def copy(self) -> Definitions:
        other = Definitions()
        other._msgs, other._srvs, other._actions = dict(self._msgs), dict(self._srvs), dict(self._actions)
        other._typestore = self._typestore
        return other

    # --- lookup -----------------------------------------------------------------------------

    def msg(self, name: str) -> MsgDef:
        """A message definition; also the parts of services and actions ('pkg/srv/X_Request')."""
        if name.count('/') == 2 and name.split('/')[1] in ('srv', 'action'):
            pkg_kind, _, part = name.rpartition('_')
            whole = self._srvs.get(pkg_kind) or self._actions.get(pkg_kind) or self.derived(pkg_kind)
            found = getattr(whole, part.lower(), None) if whole else None
            if isinstance(found, MsgDef):
                return found
            found = self.derived(name)
            if isinstance(found, MsgDef):
                return found
        full = normalize(name, 'msg')
        try:
            return self._msgs[full]
        except KeyError:
            raise UnknownType(f'unknown message type {name!r}') from None

    def srv(self, name: str) -> SrvDef:
        """A service definition; also an action's derived services ('pkg/action/X_SendGoal')."""
        found = self.derived(name)
        if isinstance(found, SrvDef):
            return found
        try:
            return self._srvs[normalize(name, 'srv')]
        except KeyError:
            raise UnknownType(f'unknown service type {name!r}') from None

    def action(self, name: str) -> ActionDef:
        try:
            return self._actions[normalize(name, 'action')]
        except KeyError:
            raise UnknownType(f'unknown action type {name!r}') from None

    def derived(self, name: str) -> SrvDef | MsgDef | None:
        """``pkg/action/X_SendGoal``, ``X_GetResult`` (services) or ``X_FeedbackMessage`` (a message)
        of action X, with the fields rosidl gives them; None for any other name, UnknownType when
        X is unknown."""
        parts = name.split('/') if isinstance(name, str) else ()
        if len(parts) != 3 or parts[1] != 'action':
            return None
        base, _, part = parts[2].rpartition('_')
        if not base or part not in DERIVED:
            return None
        found = self._derived.get(name)
        if found is None:
            action = self.action(f'{parts[0]}/action/{base}')
            goal_id = Field('goal_id', 'unique_identifier_msgs/msg/UUID')
            if part == 'FeedbackMessage':
                found = MsgDef(name, (goal_id, Field('feedback', action.feedback.type)))
                if self._typestore is not None and name not in self._typestore.types:   # for cbor-raw
                    from rosbags.interfaces import Nodetype  # noqa: PLC0415
                    self._typestore.register({name: ([], [(f.name, (Nodetype.NAME, f.type)) for f in found.fields])})
            elif part == 'SendGoal':
                found = SrvDef(name, MsgDef(f'{name}_Request', (goal_id, Field('goal', action.goal.type))),
                               MsgDef(f'{name}_Response', (Field('accepted', 'bool'),
                                                           Field('stamp', 'builtin_interfaces/msg/Time'))))
            else:
                found = SrvDef(name, MsgDef(f'{name}_Request', (goal_id,)),
                               MsgDef(f'{name}_Response', (Field('status', 'int8'),
                                                           Field('result', action.result.type))))
            self._derived[name] = found
        return found

    def interfaces(self) -> list[str]:
        return sorted([*self._msgs, *self._srvs, *self._actions])

    @property
    def typestore(self):
        """The rosbags typestore (for CDR), with every message and srv/action part registered."""
        return self._typestore

    # --- rosapi views -----------------------------------------------------------------------

    def typedefs(self, root: MsgDef) -> list[dict]:
        """rosapi TypeDefs for a message and every message type nested in it, root first."""
        out: list[dict] = []
        seen: set[str] = set()

        def visit(msg: MsgDef) -> None:
            if msg.type in seen:
                return
            seen.add(msg.type)
            out.append(typedef(msg))
            for f in msg.fields:
                if not f.primitive:
                    visit(self.msg(f.type))

        visit(root)
        return out

    def full_text(self, root: MsgDef) -> str:
        """The definition text with every dependency appended, as ``gendeps --cat`` prints it."""
        parts, seen, queue = [], set(), [root]
        while queue:
            msg = queue.pop(0)
            if msg.type in seen:
                continue
            seen.add(msg.type)
            if parts:
                parts.append('=' * 80 + f'\nMSG: {short_name(msg.type)}')
            parts.append(definition_text(msg))
            queue.extend(self.msg(f.type) for f in msg.fields if not f.primitive)
        return '\n'.join(parts)


def typedef(msg: MsgDef) -> dict:
    names, types, lens, examples = [], [], [], []
    for f in msg.fields:
        names.append(f.name)
        types.append(f.type if f.primitive else short_name(f.type))
        lens.append(-1 if f.array is None else f.array)
        examples.append('[]' if f.array is not None else str(example_value(f)))
    return {
        'type': short_name(msg.type), 'fieldnames': names, 'fieldtypes': types,
        'fieldarraylen': lens, 'examples': examples,
        'constnames': [c[0] for c in msg.constants], 'constvalues': [str(c[2]) for c in msg.constants],
    }


def example_value(f: Field):
    return scalar_default(f) if f.primitive else {}


def scalar_default(f: Field):
    """The default of a primitive field: 0, 0.0, False or ''."""
    if f.type in FLOATS:
        return 0.0
    if f.type == 'bool':
        return False
    if f.type in ('string', 'wstring'):
        return ''
    return 0


def definition_text(msg: MsgDef) -> str:
    lines = []
    for name, type_, value in msg.constants:
        lines.append(f'{type_} {name}={_literal(value)}')
    for f in msg.fields:
        t = f.type if f.primitive else short_name(f.type)
        if f.string_bound:
            t += f'<={f.string_bound}'
        if f.array is not None:
            t += f'[{f.array}]' if f.array else (f'[<={f.bound}]' if f.bound else '[]')
        lines.append(f'{t} {f.name}' if f.default is None else f'{t} {f.name} {_literal(f.default)}')
    return '\n'.join(lines)


def parse_msg(name: str, text: str) -> MsgDef:
    """Parse .msg text (as in a .msg file or one section of .srv/.action) into a MsgDef.

    rosbags' parser is the one parser of message texts here (its typestore reads what this
    returns, through ``definition_text``): a parser of our own cut ``string C="x#y"`` at the
    ``#`` and dropped field defaults. Names without a package resolve in ``pkg/msg/`` (a
    service's fields too); ``Header`` and ``time`` as ROS 2 spells them. ValueError on bad text."""
    from rosbags.typesys import TypesysError  # noqa: PLC0415 (rosbags is heavy; load once)
    from rosbags.typesys.base import BaseType, Cardinality  # noqa: PLC0415
    from rosbags.typesys.msg import MSGParser  # noqa: PLC0415

    pkg, short = name.split('/')[0], name.rpartition('/')[2]
    whole = f'MSG: {pkg}/msg/{short}\n{text}\n'   # a message of pkg/msg: relative names resolve there
    try:
        [parsed] = MSGParser(whole).specification()
    except TypesysError as e:
        raise ValueError(f'{name}: cannot parse line {_failed_line(whole, str(e))!r}') from None
    consts = tuple((c.name, c.typ.value, _const(c.typ.value, c.value)) for c in parsed.constants)
    fields = []
    for f in parsed.fields:
        t = f.typ
        type_ = t.ref.name.value if isinstance(t.ref, BaseType) else t.ref.name
        array = bound = None
        if t.cardinality == Cardinality.ARRAY:
            array = t.size
        elif t.cardinality == Cardinality.SEQUENCE:
            array, bound = 0, t.size
        default = f.value
        if default is not None:
            default = (tuple(_const(type_, v) for v in default) if isinstance(default, list)
                       else _const(type_, default))
        fields.append(Field(f.name, type_, array, bound or 0, t.str_size, default))
    return MsgDef(name, tuple(fields), consts)


def _failed_line(whole: str, error: str) -> str:
    """The line of the text where rosbags' parser stopped (its error gives the offset)."""
    parts = error.split('\n')
    pos = int(parts[2]) if len(parts) > 2 and parts[2].isdigit() else 0
    rest = whole[pos:].lstrip('\n')
    return rest.split('\n', 1)[0] if rest else whole.split('\n', 1)[-1].strip()


def _const(type_: str, value):
    """A constant or default as its type holds it (rosbags reads ``float64 X=1`` as the int 1)."""
    if type_ == 'bool':
        return bool(value)
    if type_ in INTEGERS:
        return int(value)
    if type_ in FLOATS:
        return float(value)
    return value if isinstance(value, str) else str(value)


def _literal(value) -> str:
    """A value as message text writes it, read back the same by rosbags' parser."""
    if isinstance(value, tuple):
        return f'[{", ".join(_literal(v) for v in value)}]'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if not isinstance(value, str):
        return repr(value)
    for quote in ('"', "'"):
        if quote not in value and '\\' not in value:
            return f'{quote}{value}{quote}'
    return value   # unquoted: the rest of the line


def _register_parts(defs: Definitions, typestore) -> None:
    """Register the srv/action parts with rosbags so CDR (cbor-raw) works for them too."""
    from rosbags.typesys import get_types_from_msg  # noqa: PLC0415

    parts = [*((s.request, s.response) for s in defs._srvs.values()),
             *((a.goal, a.result, a.feedback) for a in defs._actions.values())]
    msgs = [m for group in parts for m in group]
    msgs += [m for n, m in defs._msgs.items() if n not in typestore.fielddefs]
    types = {}
    for m in msgs:
        for key, value in get_types_from_msg(definition_text(m), m.type).items():
            types[m.type if key.replace('/msg/', '/', 1) == m.type.replace('/msg/', '/', 1) else key] = value
    typestore.register(types)


@cache
def _jazzy() -> Definitions:
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415

    typestore = get_typestore(Stores.ROS2_JAZZY)
    defs = Definitions()
    defs.load_typestore(typestore)
    defs.load_dir(INTERFACES_DIR)
    _register_parts(defs, typestore)
    return defs


def _jazzy_copy() -> Definitions:
    return _jazzy().copy()
