"""The Foxglove WebSocket protocol (``foxglove.websocket.v1``, and ``foxglove.sdk.v1`` where it
differs), sans-I/O: client frames in, typed ops or a ``ProtocolError`` naming the op out; the
server's messages as frames.

What Foxglove and Lichtblick speak (npm ``@foxglove/ws-protocol`` 0.8, the legacy spec of
foxglove/ws-protocol, and foxglove/foxglove-sdk's ``protocol/v1``): JSON text frames with an
``op``, and binary frames whose first byte is an opcode, integers little-endian. ``foxglove.sdk.v1``
is the same wire with a few additions: optional channel ``metadata``, playback control (binary
opcode 3 from the client, 5 from the server) and ``dataStartTime``/``dataEndTime`` for servers that
play files. A live gateway plays nothing: playback control is answered with an error naming it.

ROS 2 mapping, as foxglove_bridge does it: a channel per topic with ``cdr`` encoding and a
``ros2msg`` schema (the type's definition with every dependency appended, ``gendeps --cat``'s
text); services with ``cdr`` request and response schemas named ``pkg/srv/X_Request`` and
``..._Response``; parameters named ``/node.param`` (the node's full name, a dot, the parameter).
"""

from __future__ import annotations

import base64
import binascii
import math
import struct
from dataclasses import dataclass
from typing import Any, ClassVar

from .codec import decode_text, dumps
from .errors import ProtocolError, json_type, shown

WEBSOCKET_V1, SDK_V1 = 'foxglove.websocket.v1', 'foxglove.sdk.v1'
SUBPROTOCOLS = (SDK_V1, WEBSOCKET_V1)
CAPABILITIES = ('clientPublish', 'parameters', 'parametersSubscribe', 'services', 'connectionGraph')
ENCODINGS = ('cdr', 'json')       # what clients may publish and call services in
SCHEMA_ENCODING = 'ros2msg'
LEVELS = {'info': 0, 'warning': 1, 'warn': 1, 'error': 2}
PARAM_SEP = '.'
UINT32 = 2**32 - 1

# binary opcodes: client -> server, server -> client
CLIENT_MESSAGE_DATA, SERVICE_CALL_REQUEST, PLAYBACK_CONTROL = 0x01, 0x02, 0x03
MESSAGE_DATA, SERVICE_CALL_RESPONSE, FETCH_ASSET_RESPONSE = 0x01, 0x03, 0x04   # (0x02: time, not sent)
_MESSAGE_DATA = struct.Struct('<BIQ')
_U32 = struct.Struct('<I')
_CALL = struct.Struct('<III')


def choose(offered) -> str | None:
    """The subprotocol to answer a websocket upgrade with: the first the client offers that this
    module speaks, or None (a rosbridge client, which offers none or another)."""
    for name in offered or ():
        if name in SUBPROTOCOLS:
            return name
    return None


# --- client ops --------------------------------------------------------------------------------

class _Bad(Exception):
    """A field failed its check: (what it must be, the field's path)."""


def _uint32(v, path: str) -> int:
    if type(v) is not int:
        raise _Bad(f'must be an integer, got {json_type(v)}', path)
    if not 0 <= v <= UINT32:
        raise _Bad(f'must be an integer from 0 to {UINT32}, got {shown(v)}', path)
    return v


def _string(v, path: str) -> str:
    if type(v) is not str:
        raise _Bad(f'must be a string, got {json_type(v)}', path)
    return v


def _list(v, path: str, item) -> tuple:
    if type(v) is not list:
        raise _Bad(f'must be an array, got {json_type(v)}', path)
    return tuple(item(x, f'{path}[{i}]') for i, x in enumerate(v))


def _object(v, path: str) -> dict:
    if type(v) is not dict:
        raise _Bad(f'must be an object, got {json_type(v)}', path)
    return v


def _get(obj: dict, key: str, path: str, check, required: bool = True, default=None):
    value = obj.get(key)
    if value is None:
        if required:
            raise _Bad('is required' if key not in obj else 'must not be null', f'{path}{key}')
        return default
    return check(value, f'{path}{key}')


@dataclass(frozen=True, slots=True)
class Subscription:
    id: int
    channel_id: int


@dataclass(frozen=True, slots=True)
class Subscribe:
    OP: ClassVar[str] = 'subscribe'
    subscriptions: tuple[Subscription, ...]

    @classmethod
    def parse(cls, obj: dict) -> Subscribe:
        def one(v, path):
            _object(v, path)
            return Subscription(_get(v, 'id', f'{path}.', _uint32), _get(v, 'channelId', f'{path}.', _uint32))
        return cls(_get(obj, 'subscriptions', '', lambda v, p: _list(v, p, one)))


@dataclass(frozen=True, slots=True)
class Unsubscribe:
    OP: ClassVar[str] = 'unsubscribe'
    subscription_ids: tuple[int, ...]

    @classmethod
    def parse(cls, obj: dict) -> Unsubscribe:
        return cls(_get(obj, 'subscriptionIds', '', lambda v, p: _list(v, p, _uint32)))


@dataclass(frozen=True, slots=True)
class ClientChannel:
    id: int
    topic: str
    encoding: str
    schema_name: str
    schema: str | None = None
    schema_encoding: str | None = None


@dataclass(frozen=True, slots=True)
class Advertise:
    """A client's channels to publish on (the ``clientPublish`` capability)."""
    OP: ClassVar[str] = 'advertise'
    channels: tuple[ClientChannel, ...]

    @classmethod
    def parse(cls, obj: dict) -> Advertise:
        def one(v, path):
            _object(v, path)
            p = f'{path}.'
            return ClientChannel(_get(v, 'id', p, _uint32), _get(v, 'topic', p, _string),
                                 _get(v, 'encoding', p, _string), _get(v, 'schemaName', p, _string),
                                 _get(v, 'schema', p, _string, False), _get(v, 'schemaEncoding', p, _string, False))
        return cls(_get(obj, 'channels', '', lambda v, p: _list(v, p, one)))


@dataclass(frozen=True, slots=True)
class Unadvertise:
    OP: ClassVar[str] = 'unadvertise'
    channel_ids: tuple[int, ...]

    @classmethod
    def parse(cls, obj: dict) -> Unadvertise:
        return cls(_get(obj, 'channelIds', '', lambda v, p: _list(v, p, _uint32)))


UNSET = None   # a setParameters value left out: the parameter is to be removed


@dataclass(frozen=True, slots=True)
class Parameter:
    name: str
    value: Any = UNSET
    type: str | None = None   # byte_array, float64, float64_array

    def ros_value(self) -> Any:
        """The value as the backends take it: base64 byte arrays decoded, float64 made float."""
        return ros_value(self.value, self.type, self.name)


PARAM_TYPES = ('byte_array', 'float64', 'float64_array')


def _param(v, path: str) -> Parameter:
    _object(v, path)
    p = f'{path}.'
    kind = _get(v, 'type', p, _string, False)
    if kind is not None and kind not in PARAM_TYPES:
        raise _Bad(f"must be one of {', '.join(PARAM_TYPES)}, got {shown(kind)}", f'{p}type')
    param = Parameter(_get(v, 'name', p, _string), v.get('value'), kind)
    try:
        param.ros_value()
    except ValueError as e:
        raise _Bad(str(e), f'{p}value') from None
    return param


@dataclass(frozen=True, slots=True)
class GetParameters:
    OP: ClassVar[str] = 'getParameters'
    names: tuple[str, ...]
    id: str | None = None

    @classmethod
    def parse(cls, obj: dict) -> GetParameters:
        return cls(_get(obj, 'parameterNames', '', lambda v, p: _list(v, p, _string)),
                   _get(obj, 'id', '', _string, False))


@dataclass(frozen=True, slots=True)
class SetParameters:
    OP: ClassVar[str] = 'setParameters'
    parameters: tuple[Parameter, ...]
    id: str | None = None

    @classmethod
    def parse(cls, obj: dict) -> SetParameters:
        return cls(_get(obj, 'parameters', '', lambda v, p: _list(v, p, _param)), _get(obj, 'id', '', _string, False))


@dataclass(frozen=True, slots=True)
class SubscribeParameterUpdates:
    OP: ClassVar[str] = 'subscribeParameterUpdates'
    names: tuple[str, ...]   # empty: every parameter known now

    @classmethod
    def parse(cls, obj: dict):
        return cls(_get(obj, 'parameterNames', '', lambda v, p: _list(v, p, _string)))


@dataclass(frozen=True, slots=True)
class UnsubscribeParameterUpdates(SubscribeParameterUpdates):
    OP: ClassVar[str] = 'unsubscribeParameterUpdates'


@dataclass(frozen=True, slots=True)
class SubscribeConnectionGraph:
    OP: ClassVar[str] = 'subscribeConnectionGraph'

    @classmethod
    def parse(cls, obj: dict):
        return cls()


@dataclass(frozen=True, slots=True)
class UnsubscribeConnectionGraph(SubscribeConnectionGraph):
    OP: ClassVar[str] = 'unsubscribeConnectionGraph'


@dataclass(frozen=True, slots=True)
class FetchAsset:
    OP: ClassVar[str] = 'fetchAsset'
    uri: str
    request_id: int

    @classmethod
    def parse(cls, obj: dict) -> FetchAsset:
        return cls(_get(obj, 'uri', '', _string), _get(obj, 'requestId', '', _uint32))


@dataclass(frozen=True, slots=True)
class MessageData:
    """Binary opcode 0x01 from a client: a message on one of its advertised channels."""
    OP: ClassVar[str] = 'messageData'
    channel_id: int
    data: bytes


@dataclass(frozen=True, slots=True)
class ServiceCallRequest:
    """Binary opcode 0x02: a call of an advertised service."""
    OP: ClassVar[str] = 'serviceCallRequest'
    service_id: int
    call_id: int
    encoding: str
    data: bytes


JSON_OPS: dict[str, type] = {cls.OP: cls for cls in (
    Subscribe, Unsubscribe, Advertise, Unadvertise, GetParameters, SetParameters, SubscribeParameterUpdates,
    UnsubscribeParameterUpdates, SubscribeConnectionGraph, UnsubscribeConnectionGraph, FetchAsset)}
Op = (Subscribe | Unsubscribe | Advertise | Unadvertise | GetParameters | SetParameters | SubscribeParameterUpdates
      | UnsubscribeParameterUpdates | SubscribeConnectionGraph | UnsubscribeConnectionGraph | FetchAsset
      | MessageData | ServiceCallRequest)


def parse_text(data: str | bytes) -> Op:
    """One JSON text frame as an op; ProtocolError naming the op and the field otherwise."""
    obj = decode_text(data)
    op = obj.get('op')
    rid = obj.get('id') if type(obj.get('id')) is str else None
    if op is None:
        raise ProtocolError("missing required field 'op'", id=rid)
    if type(op) is not str:
        raise ProtocolError(f"field 'op' must be a string, got {json_type(op)}", id=rid)
    cls = JSON_OPS.get(op)
    if cls is None:
        raise ProtocolError(f'unknown op {shown(op)} (this server takes {", ".join(JSON_OPS)})', op=op, id=rid)
    try:
        return cls.parse(obj)
    except _Bad as e:
        raise ProtocolError(f"field '{e.args[1]}' {e.args[0]}", op=op, id=rid) from None


def parse_binary(data: bytes | memoryview) -> Op:
    """One binary frame: the opcode, then its fields."""
    view = memoryview(data)
    if not len(view):
        raise ProtocolError('empty binary message (it must start with an opcode)')
    opcode = view[0]
    if opcode == CLIENT_MESSAGE_DATA:
        if len(view) < 5:
            raise ProtocolError(f'binary message of {len(view)} bytes is too short for a channel id',
                                op=MessageData.OP)
        return MessageData(_U32.unpack_from(view, 1)[0], bytes(view[5:]))
    if opcode == SERVICE_CALL_REQUEST:
        if len(view) < 13:
            raise ProtocolError(f'binary message of {len(view)} bytes is too short for service id, call id '
                                'and encoding length', op=ServiceCallRequest.OP)
        service_id, call_id, size = _CALL.unpack_from(view, 1)
        if len(view) < 13 + size:
            raise ProtocolError(f'encoding of {size} bytes runs past the end of the message',
                                op=ServiceCallRequest.OP, id=str(call_id))
        try:
            encoding = bytes(view[13:13 + size]).decode('utf-8')
        except UnicodeDecodeError:
            raise ProtocolError('the encoding is not UTF-8 text', op=ServiceCallRequest.OP, id=str(call_id)) from None
        return ServiceCallRequest(service_id, call_id, encoding, bytes(view[13 + size:]))
    if opcode == PLAYBACK_CONTROL:
        raise ProtocolError('this server streams a live graph: it has no playbackControl capability',
                            op='playbackControlRequest')
    raise ProtocolError(f'unknown binary opcode 0x{opcode:02x} (this server takes 0x01 message data '
                        'and 0x02 service call requests)')


# --- parameter values --------------------------------------------------------------------------

def split_parameter(name: str) -> tuple[str, str]:
    """'/turtlesim.background_r' -> ('/turtlesim', 'background_r'): node names have no dots,
    parameter names may ('qos_overrides./tf.depth')."""
    node, sep, param = name.partition(PARAM_SEP)
    if not sep or not node or not param:
        raise ValueError(f'parameter names are "/node.parameter", got {shown(name)}')
    return node if node.startswith('/') else '/' + node, param


def parameter_name(node: str, param: str) -> str:
    return f'{node}{PARAM_SEP}{param}'


def _number(v) -> bool:
    return type(v) in (int, float)


def ros_value(value, kind: str | None, name: str = '') -> Any:
    """A Foxglove parameter value as ROS takes it (ValueError when it does not fit its type)."""
    if kind == 'byte_array':
        if type(value) is not str:
            raise ValueError(f'a byte_array value is base64 text, got {json_type(value)}')
        try:
            return base64.b64decode(value, validate=True)
        except binascii.Error:
            raise ValueError(f'a byte_array value is base64 text, got {shown(value)}') from None
    if kind == 'float64':
        if not _number(value):
            raise ValueError(f'a float64 value is a number, got {json_type(value)}')
        return float(value)
    if kind == 'float64_array':
        if type(value) is not list or not all(_number(v) for v in value):
            raise ValueError('a float64_array value is an array of numbers')
        return [float(v) for v in value]
    return value


def foxglove_parameter(name: str, value) -> dict:
    """A ROS parameter value as a Foxglove parameter: floats typed float64 (a JavaScript number
    cannot tell 1.0 from 1), byte arrays as base64, lists of floats typed float64_array."""
    out: dict = {'name': name, 'value': value}
    if type(value) is float:
        if not math.isfinite(value):
            out['value'] = None   # JSON has no NaN or infinity
        out['type'] = 'float64'
    elif isinstance(value, (bytes, bytearray)):
        out['value'], out['type'] = base64.b64encode(value).decode('ascii'), 'byte_array'
    elif isinstance(value, (list, tuple)):
        out['value'] = list(value)
        if value and all(type(v) is float for v in value):
            out['type'] = 'float64_array'
    return out


# --- server messages -----------------------------------------------------------------------------

def server_info(name: str, capabilities, session_id: str, metadata: dict | None = None) -> bytes:
    info = {'op': 'serverInfo', 'name': name, 'capabilities': list(capabilities),
            'supportedEncodings': list(ENCODINGS), 'sessionId': session_id}
    if metadata:
        info['metadata'] = metadata
    return dumps(info)


def status(level: str, message: str, id: str | None = None) -> bytes:
    out = {'op': 'status', 'level': LEVELS.get(level, 2), 'message': message}
    if id is not None:
        out['id'] = id
    return dumps(out)


def channel(id: int, topic: str, schema_name: str, schema: str) -> dict:
    """A server channel of a ROS 2 topic: CDR messages, a ros2msg schema."""
    return {'id': id, 'topic': topic, 'encoding': 'cdr', 'schemaName': schema_name, 'schema': schema,
            'schemaEncoding': SCHEMA_ENCODING}


def advertise(channels) -> bytes:
    return dumps({'op': 'advertise', 'channels': list(channels)})


def unadvertise(ids) -> bytes:
    return dumps({'op': 'unadvertise', 'channelIds': list(ids)})


def service(id: int, name: str, type: str, request: tuple[str, str], response: tuple[str, str]) -> dict:
    """A ROS 2 service; request and response are (schema name, schema text). The request and
    response objects are what Foxglove reads now; requestSchema and responseSchema what older
    clients read (their encoding then is the first of supportedEncodings: cdr)."""
    def part(schema_name: str, schema: str) -> dict:
        return {'encoding': 'cdr', 'schemaName': schema_name, 'schemaEncoding': SCHEMA_ENCODING, 'schema': schema}
    return {'id': id, 'name': name, 'type': type, 'request': part(*request), 'response': part(*response),
            'requestSchema': request[1], 'responseSchema': response[1]}


def advertise_services(services) -> bytes:
    return dumps({'op': 'advertiseServices', 'services': list(services)})


def unadvertise_services(ids) -> bytes:
    return dumps({'op': 'unadvertiseServices', 'serviceIds': list(ids)})


def parameter_values(parameters, id: str | None = None) -> bytes:
    out: dict = {'op': 'parameterValues', 'parameters': list(parameters)}
    if id is not None:
        out['id'] = id
    return dumps(out)


def service_call_failure(service_id: int, call_id: int, message: str) -> bytes:
    return dumps({'op': 'serviceCallFailure', 'serviceId': service_id, 'callId': call_id, 'message': message})


def connection_graph_update(published: dict, subscribed: dict, services: dict, removed_topics=(),
                            removed_services=()) -> bytes:
    """published/subscribed: topic -> node names; services: service -> node names. Each entry
    replaces what the client knew of that name; removed names are gone."""
    return dumps({
        'op': 'connectionGraphUpdate',
        'publishedTopics': [{'name': n, 'publisherIds': sorted(ids)} for n, ids in published.items()],
        'subscribedTopics': [{'name': n, 'subscriberIds': sorted(ids)} for n, ids in subscribed.items()],
        'advertisedServices': [{'name': n, 'providerIds': sorted(ids)} for n, ids in services.items()],
        'removedTopics': sorted(removed_topics), 'removedServices': sorted(removed_services)})


def message_data_header(subscription_id: int, timestamp_ns: int) -> bytes:
    """The 13 bytes before a message's payload: opcode, subscription id, receive time (ns)."""
    return _MESSAGE_DATA.pack(MESSAGE_DATA, subscription_id, timestamp_ns)


def service_call_response(service_id: int, call_id: int, encoding: str, payload: bytes) -> bytes:
    name = encoding.encode('utf-8')
    return b''.join((bytes((SERVICE_CALL_RESPONSE,)), _CALL.pack(service_id, call_id, len(name)), name, payload))


def fetch_asset_response(request_id: int, data: bytes = b'', error: str | None = None) -> bytes:
    """The asset's bytes (status 0), or why not (status 1)."""
    message = (error or '').encode('utf-8')
    return b''.join((struct.pack('<BIBI', FETCH_ASSET_RESPONSE, request_id, 1 if error is not None else 0,
                                 len(message)), message, data if error is None else b''))
