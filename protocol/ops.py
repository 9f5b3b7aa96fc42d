"""Incoming rosbridge v2 ops: one frozen dataclass per op, parsed and validated by field tables."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from .errors import ProtocolError, json_type, shown

COMPRESSIONS = ('none', 'png', 'cbor', 'cbor-raw')
LEVELS = ('info', 'warning', 'error', 'none')
MAX_INT = 2**31 - 1            # counts, sizes and milliseconds in op fields
MAX_SECONDS = 10.0**9          # timeouts


class _Bad(Exception):
    """A field failed its check; parse_op turns it into a ProtocolError sentence."""


class Check:
    """How one wire field is validated: required or not, and a checker of its value."""

    __slots__ = ('check', 'required')

    def __init__(self, check, required: bool = False) -> None:
        self.check = check
        self.required = required


def _string(v):
    if type(v) is str:
        return v
    raise _Bad('must be a string')


def _ident(v):
    if type(v) is str:
        return v
    if type(v) is int and v.bit_length() <= 64:
        return str(v)
    raise _Bad('must be a string')


def _boolean(v):
    if type(v) is bool:
        return v
    raise _Bad('must be a boolean')


def _integer(minimum: int = -MAX_INT - 1, maximum: int = MAX_INT):
    def check(v):
        if type(v) is not int:
            raise _Bad('must be an integer')
        if v < minimum:
            raise _Bad(f'must be >= {minimum}', v)
        if v > maximum:
            raise _Bad(f'must be <= {maximum}', v)
        return v
    return check


def _number(minimum: float | None = None, maximum: float = MAX_SECONDS):
    def check(v):
        if type(v) is not int and type(v) is not float:
            raise _Bad('must be a number')
        if minimum is not None and not v >= minimum:
            raise _Bad(f'must be >= {minimum}', v)
        if not v <= maximum:
            raise _Bad(f'must be <= {maximum:g}', v)
        return float(v)
    return check


def _obj(v):
    if type(v) is dict:
        return v
    raise _Bad('must be an object')


def _obj_or_list(v):
    if type(v) is dict or type(v) is list:
        return v
    raise _Bad('must be an object or an array')


def _any(v):
    return v


def _enum(*choices: str, aliases: dict[str, str] | None = None):
    aliases = aliases or {}

    def check(v):
        if type(v) is not str:
            raise _Bad('must be a string')
        v = aliases.get(v, v)
        if v not in choices:
            raise _Bad(f"must be one of {', '.join(choices)}", v)
        return v
    return check


STR, STR_REQ = Check(_string), Check(_string, True)
ID, ID_REQ = Check(_ident), Check(_ident, True)
BOOL = Check(_boolean)
OBJ, OBJ_REQ = Check(_obj), Check(_obj, True)
ARGS = Check(_obj_or_list)
ANY = Check(_any)
NONNEG = Check(_integer(0))
STAMP = Check(_number(0.0, 2.0**53))   # a client's clock in ms (rosgate's extension: docs/protocol.md)
FRAGMENT_SIZE = Check(_integer(1))
COMPRESSION = Check(_enum(*COMPRESSIONS))


@dataclass(frozen=True, slots=True)
class ImageSpec:
    """What a subscriber asks of an image topic (the ``image`` extension field of subscribe):
    at most width x height pixels (a missing side follows the image's aspect ratio; never larger
    than the image), as JPEG of this quality; on a map (OccupancyGrid), at most width x height
    cells. Hashable: one encode per spec, shared."""
    width: int | None = None
    height: int | None = None
    quality: int = 75


MAX_IMAGE_SIDE = 8192
_IMAGE_KEYS = {'width': (1, MAX_IMAGE_SIDE), 'height': (1, MAX_IMAGE_SIDE), 'quality': (1, 100)}


def _image(v):
    if type(v) is not dict:
        raise _Bad('must be an object like {"width": 320, "height": 240, "quality": 60}')
    for key, value in v.items():
        if key not in _IMAGE_KEYS:
            raise _Bad(f"has an unknown key {shown(key)} (known: width, height, quality)", v)
        low, high = _IMAGE_KEYS[key]
        if type(value) is not int or not low <= value <= high:
            raise _Bad(f"'{key}' must be an integer from {low} to {high}", v)
    return ImageSpec(v.get('width'), v.get('height'), v.get('quality', 75))


IMAGE = Check(_image)
MAX_CLOUD_POINTS = 1_000_000
CLOUD_POINTS = Check(_integer(1, MAX_CLOUD_POINTS))


@dataclass(frozen=True, slots=True)
class Advertise:
    OP: ClassVar[str] = 'advertise'
    SPEC: ClassVar = {'topic': STR_REQ, 'type': STR_REQ, 'id': ID, 'latch': BOOL, 'queue_size': NONNEG,
                      'qos': OBJ}
    topic: str
    type: str
    id: str | None = None
    latch: bool = False
    queue_size: int = 100
    qos: dict | None = None


@dataclass(frozen=True, slots=True)
class Unadvertise:
    OP: ClassVar[str] = 'unadvertise'
    SPEC: ClassVar = {'topic': STR_REQ, 'id': ID}
    topic: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class Publish:
    OP: ClassVar[str] = 'publish'
    SPEC: ClassVar = {'topic': STR_REQ, 'msg': OBJ_REQ, 'id': ID, 'latch': BOOL, 'queue_size': NONNEG,
                      'type': STR, 't': STAMP}
    topic: str
    msg: dict
    id: str | None = None
    latch: bool = False
    queue_size: int = 100
    type: str | None = None
    t: float | None = None   # when the client made it, its clock in ms (extension; others ignore it)


@dataclass(frozen=True, slots=True)
class Subscribe:
    OP: ClassVar[str] = 'subscribe'
    SPEC: ClassVar = {'topic': STR_REQ, 'id': ID, 'type': STR, 'throttle_rate': NONNEG,
                      'queue_length': NONNEG, 'fragment_size': FRAGMENT_SIZE, 'compression': COMPRESSION,
                      'qos': OBJ, 'image': IMAGE, 'points': CLOUD_POINTS}
    topic: str
    id: str | None = None
    type: str | None = None
    throttle_rate: int = 0
    queue_length: int = 0
    fragment_size: int | None = None
    compression: str = 'none'
    qos: dict | None = None
    image: ImageSpec | None = None   # extension: a smaller or lower-quality JPEG of an image topic
    points: int | None = None        # extension: a PointCloud2 thinned to at most this many points


@dataclass(frozen=True, slots=True)
class Unsubscribe:
    OP: ClassVar[str] = 'unsubscribe'
    SPEC: ClassVar = {'topic': STR_REQ, 'id': ID}
    topic: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class CallService:
    OP: ClassVar[str] = 'call_service'
    SPEC: ClassVar = {'service': STR_REQ, 'id': ID, 'args': ARGS, 'type': STR, 'timeout': Check(_number(0)),
                      'fragment_size': FRAGMENT_SIZE, 'compression': COMPRESSION}
    service: str
    id: str | None = None
    args: dict | list | None = None
    type: str | None = None
    timeout: float | None = None
    fragment_size: int | None = None
    compression: str = 'none'


@dataclass(frozen=True, slots=True)
class ServiceResponse:
    OP: ClassVar[str] = 'service_response'
    SPEC: ClassVar = {'service': STR_REQ, 'id': ID, 'values': ANY, 'result': BOOL}
    service: str
    id: str | None = None
    values: Any = None
    result: bool = True


@dataclass(frozen=True, slots=True)
class AdvertiseService:
    OP: ClassVar[str] = 'advertise_service'
    SPEC: ClassVar = {'service': STR_REQ, 'type': STR_REQ, 'id': ID}
    service: str
    type: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class UnadvertiseService:
    OP: ClassVar[str] = 'unadvertise_service'
    SPEC: ClassVar = {'service': STR_REQ, 'id': ID}
    service: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class AdvertiseAction:
    OP: ClassVar[str] = 'advertise_action'
    SPEC: ClassVar = {'action': STR_REQ, 'type': STR_REQ, 'id': ID}
    action: str
    type: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class UnadvertiseAction:
    OP: ClassVar[str] = 'unadvertise_action'
    SPEC: ClassVar = {'action': STR_REQ, 'id': ID}
    action: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class SendActionGoal:
    OP: ClassVar[str] = 'send_action_goal'
    SPEC: ClassVar = {'action': STR_REQ, 'action_type': STR_REQ, 'id': ID, 'args': ARGS, 'feedback': BOOL,
                      'fragment_size': FRAGMENT_SIZE, 'compression': COMPRESSION}
    action: str
    action_type: str
    id: str | None = None
    args: dict | list | None = None
    feedback: bool = False
    fragment_size: int | None = None
    compression: str = 'none'


@dataclass(frozen=True, slots=True)
class CancelActionGoal:
    OP: ClassVar[str] = 'cancel_action_goal'
    SPEC: ClassVar = {'action': STR_REQ, 'id': ID_REQ}
    action: str
    id: str


@dataclass(frozen=True, slots=True)
class ActionFeedback:
    OP: ClassVar[str] = 'action_feedback'
    SPEC: ClassVar = {'action': STR_REQ, 'id': ID, 'values': ANY}
    action: str
    id: str | None = None
    values: Any = None


@dataclass(frozen=True, slots=True)
class ActionResult:
    OP: ClassVar[str] = 'action_result'
    SPEC: ClassVar = {'action': STR_REQ, 'id': ID, 'status': Check(_integer()), 'values': ANY, 'result': BOOL}
    action: str
    id: str | None = None
    status: int | None = None
    values: Any = None
    result: bool = True


@dataclass(frozen=True, slots=True)
class SetLevel:
    OP: ClassVar[str] = 'set_level'
    SPEC: ClassVar = {'level': Check(_enum(*LEVELS, aliases={'warn': 'warning'}), True), 'id': ID}
    level: str
    id: str | None = None


@dataclass(frozen=True, slots=True)
class Auth:
    OP: ClassVar[str] = 'auth'
    SPEC: ClassVar = {'id': ID, 'mac': STR, 'client': STR, 'dest': STR, 'rand': STR, 't': ANY, 'level': STR,
                      'end': ANY, 'token': STR}
    id: str | None = None
    mac: str | None = None
    client: str | None = None
    dest: str | None = None
    rand: str | None = None
    t: Any = None
    level: str | None = None
    end: Any = None
    token: str | None = None


@dataclass(frozen=True, slots=True)
class Fragment:
    OP: ClassVar[str] = 'fragment'
    SPEC: ClassVar = {'id': ID_REQ, 'data': STR_REQ, 'num': Check(_integer(0), True),
                      'total': Check(_integer(1), True)}
    id: str
    data: str
    num: int
    total: int


@dataclass(frozen=True, slots=True)
class Ping:
    """rosgate's extension (docs/protocol.md): answered at once with a ``pong`` carrying the same
    ``id`` and ``t``, so a page sees its round trip and that the link is alive, and the gateway
    learns the client's clock (``t``, ms) before its first stamped command."""
    OP: ClassVar[str] = 'ping'
    SPEC: ClassVar = {'id': ID, 't': STAMP}
    id: str | None = None
    t: float | None = None


@dataclass(frozen=True, slots=True)
class Png:
    """A png-compressed op (rosbridge sends these to clients; accepted in for symmetry)."""
    OP: ClassVar[str] = 'png'
    SPEC: ClassVar = {'data': STR_REQ, 'id': ID, 'num': NONNEG, 'total': Check(_integer(1))}
    data: str
    id: str | None = None
    num: int | None = None
    total: int | None = None


OPS: dict[str, type] = {cls.OP: cls for cls in (
    Advertise, Unadvertise, Publish, Subscribe, Unsubscribe, CallService, ServiceResponse,
    AdvertiseService, UnadvertiseService, AdvertiseAction, UnadvertiseAction, SendActionGoal,
    CancelActionGoal, ActionFeedback, ActionResult, SetLevel, Auth, Fragment, Png, Ping)}

Op = (Advertise | Unadvertise | Publish | Subscribe | Unsubscribe | CallService | ServiceResponse
      | AdvertiseService | UnadvertiseService | AdvertiseAction | UnadvertiseAction | SendActionGoal
      | CancelActionGoal | ActionFeedback | ActionResult | SetLevel | Auth | Fragment | Png | Ping)


def peek_id(obj: object) -> str | None:
    """The op's id as a string when it has a usable one (for error replies), else None."""
    if type(obj) is dict:
        v = obj.get('id')
        if type(v) is str:
            return v
        if type(v) is int and v.bit_length() <= 64:
            return str(v)
    return None


def parse_op(obj: object) -> Op:
    """Validate one decoded op object; raise ProtocolError naming op, id and field."""
    if type(obj) is not dict:
        raise ProtocolError(f'expected a JSON object, got {json_type(obj)}')
    mid = peek_id(obj)
    op = obj.get('op')
    if op is None:
        raise ProtocolError("missing required field 'op'", id=mid)
    if type(op) is not str:
        raise ProtocolError(f"field 'op' must be a string, got {json_type(op)}", id=mid)
    cls = OPS.get(op)
    if cls is None:
        raise ProtocolError(f'unknown op {shown(op)}', op=op, id=mid)
    kwargs = {}
    for name, spec in cls.SPEC.items():
        value = obj.get(name)
        if value is None:
            if spec.required:
                if name in obj:
                    raise ProtocolError(f"{op}: field '{name}' must not be null", op=op, id=mid)
                raise ProtocolError(f"{op}: missing required field '{name}'", op=op, id=mid)
            continue
        try:
            kwargs[name] = spec.check(value)
        except _Bad as e:
            got = json_type(value) if len(e.args) == 1 else shown(e.args[1])
            raise ProtocolError(f"{op}: field '{name}' {e.args[0]}, got {got}", op=op, id=mid) from None
    return cls(**kwargs)
