"""advertise, unadvertise, publish, subscribe, unsubscribe."""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING

from protocol.convert import from_json
from protocol.errors import ProtocolError, json_type, shown
from protocol.msgdefs import normalize
from protocol.ops import MAX_INT, MAX_SECONDS, Advertise, Publish, Subscribe, Unadvertise, Unsubscribe

from ...backends.base import QoS
from ...media import images
from .. import clouds

if TYPE_CHECKING:
    from ..session import ClientSession


def qos_for(latch: bool, queue_size: int, qos: dict | None) -> QoS:
    """rosbridge's latch/queue_size, refined by the optional qos object of newer clients."""
    q = qos or {}
    depth = _qos_number(q, 'depth', queue_size if queue_size and queue_size > 0 else 10, MAX_INT)
    return QoS(
        depth=max(1, int(depth)),
        reliable=_qos_word(q, 'reliability', 'reliable') != 'best_effort',
        transient_local=latch or _qos_word(q, 'durability', '') == 'transient_local',
        history_keep_all=_qos_word(q, 'history', '') == 'keep_all',
        deadline=_qos_number(q, 'deadline', None, MAX_SECONDS),
        lifespan=_qos_number(q, 'lifespan', None, MAX_SECONDS))


def _qos_number(q: dict, key: str, default, maximum: float):
    value = q.get(key)
    if value is None:
        return default
    if type(value) not in (int, float) or not 0 <= value <= maximum:
        raise ProtocolError(f"field 'qos.{key}' must be a number in 0..{maximum:g}, got {shown(value)}")
    return value


def _qos_word(q: dict, key: str, default: str) -> str:
    value = q.get(key, default)
    if type(value) is not str:
        raise ProtocolError(f"field 'qos.{key}' must be a string, got {json_type(value)}")
    return value.lower()


def _resolve_type(s: ClientSession, topic: str, type: str | None, op: str, id: str | None) -> str:
    if type:   # unknown types fail here, naming the type; also an action's X_FeedbackMessage
        return s.backend.msg_def(type).type
    found = s.gateway.topic_type(topic)
    if found is None:
        raise ProtocolError(f'cannot infer the type of {topic}: it does not exist yet; give a type',
                            op=op, id=id)
    return found


def _advertise(s: ClientSession, topic: str, type: str, qos: QoS, op: str, id: str | None):
    pub = s.publishers.get(topic)
    if pub is not None:
        if pub.type != type:
            raise ProtocolError(f'{topic} is already advertised with type {pub.type}', op=op, id=id)
        return pub
    pub = s.gateway.publisher(topic, type, qos)
    pub.attach(s.id)
    s.publishers[topic] = pub
    return pub


def advertise(s: ClientSession, op: Advertise) -> None:
    topic = absolute(op.topic)
    type = _resolve_type(s, topic, op.type, op.OP, op.id)
    _advertise(s, topic, type, qos_for(op.latch, op.queue_size, op.qos), op.OP, op.id)


def unadvertise(s: ClientSession, op: Unadvertise) -> None:
    unadvertised(s, absolute(op.topic), s.publishers, op, lambda s, topic: s.publishers.pop(topic).detach(s.id))


def publish(s: ClientSession, op: Publish) -> None:
    topic = absolute(op.topic)
    pub = s.publishers.get(topic)
    if pub is None:   # rosbridge auto-advertises when the type can be resolved
        type = _resolve_type(s, topic, op.type, op.OP, op.id)
        pub = _advertise(s, topic, type, qos_for(op.latch, op.queue_size, None), op.OP, op.id)
    elif op.type and normalize(op.type, 'msg') != pub.type:   # never sent silently as another type
        raise ProtocolError(f'{topic} is advertised by this client with type {pub.type}, not {op.type}',
                            op=op.OP, id=op.id)
    issued = None if op.t is None else s.clock.sample(op.t, asyncio.get_running_loop().time())
    s.gateway.publish(s, pub, from_json(s.backend.defs, pub.msgdef, op.msg), issued, op.id)


def subscribe(s: ClientSession, op: Subscribe) -> None:
    topic = absolute(op.topic)
    type = _resolve_type(s, topic, op.type, op.OP, op.id)
    existing = s.subscriptions.get(topic)
    if existing is not None and existing.fanout.type != type:
        raise ProtocolError(f'{topic} is already subscribed with type {existing.fanout.type}', op=op.OP, id=op.id)
    if op.image is not None:
        if type not in images.SIZED:
            raise ProtocolError(f"{topic} is {type}: the field 'image' applies to {', '.join(images.SIZED)} "
                                'topics', op=op.OP, id=op.id)
        if op.compression == 'cbor-raw':
            raise ProtocolError("the field 'image' cannot be combined with cbor-raw (the topic's own bytes)",
                                op=op.OP, id=op.id)
    if op.points is not None:
        if type != clouds.CLOUD:
            raise ProtocolError(f"{topic} is {type}: the field 'points' applies to {clouds.CLOUD} topics",
                                op=op.OP, id=op.id)
        if op.image is not None or op.compression == 'cbor-raw':
            raise ProtocolError("the field 'points' cannot be combined with 'image' or cbor-raw", op=op.OP, id=op.id)
    measure = clouds.Target(op.points) if op.points is not None else op.image
    fan = s.gateway.fanout(topic, type)
    fresh = s.id not in fan.subscribers
    try:
        sub = fan.add(s, op.id, (op.throttle_rate, op.queue_length, op.compression, op.fragment_size, measure))
    except BaseException:   # release next to creation: a failed subscribe leaves no subscription
        if fan.unused:
            s.gateway.drop_fanout(fan)
        raise
    s.subscriptions[topic] = sub
    if fresh:
        fan.replay_latched(sub)


def unsubscribe(s: ClientSession, op: Unsubscribe) -> None:
    topic = absolute(op.topic)
    sub = s.subscriptions.get(topic)
    if sub is None:
        s.status('warning', f'not subscribed to {topic}', op.OP, op.id)
        return
    if sub.fanout.remove(s, op.id):
        del s.subscriptions[topic]


def absolute(name: str) -> str:
    return name if name.startswith('/') else '/' + name


def unadvertised(s: ClientSession, name: str, mine, op, release) -> None:
    """``release(s, name)`` when ``name`` is in ``mine`` (what this client advertised); a warning
    status when not: the unadvertise ops of topics, services and actions."""
    if name in mine:
        release(s, name)
    else:
        s.status('warning', f'{name} is not advertised by this client', op.OP, op.id)
