"""advertise, unadvertise, publish, subscribe, unsubscribe."""

from __future__ import annotations

from typing import TYPE_CHECKING

from protocol.convert import from_json
from protocol.errors import ProtocolError
from protocol.msgdefs import normalize
from protocol.ops import Advertise, Publish, Subscribe, Unadvertise, Unsubscribe

from ..backends.base import QoS

if TYPE_CHECKING:
    from ..session import ClientSession


def qos_for(latch: bool, queue_size: int, qos: dict | None) -> QoS:
    """rosbridge's latch/queue_size, refined by the optional qos object of newer clients."""
    q = qos or {}
    depth = q.get('depth', queue_size if queue_size and queue_size > 0 else 10)
    return QoS(
        depth=max(1, int(depth)),
        reliable=str(q.get('reliability', 'reliable')).lower() != 'best_effort',
        transient_local=latch or str(q.get('durability', '')).lower() == 'transient_local',
        history_keep_all=str(q.get('history', '')).lower() == 'keep_all',
        deadline=q.get('deadline'), lifespan=q.get('lifespan'))


def _resolve_type(s: ClientSession, topic: str, type: str | None, op: str, id: str | None) -> str:
    if type:
        full = normalize(type, 'msg')
        s.backend.msg_def(full)   # unknown types fail here, naming the type
        return full
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
    topic = absolute(op.topic)
    pub = s.publishers.pop(topic, None)
    if pub is None:
        s.status('warning', f'{topic} is not advertised by this client', op.OP, op.id)
        return
    pub.detach(s.id)


def publish(s: ClientSession, op: Publish) -> None:
    topic = absolute(op.topic)
    pub = s.publishers.get(topic)
    if pub is None:   # rosbridge auto-advertises when the type can be resolved
        type = _resolve_type(s, topic, op.type, op.OP, op.id)
        pub = _advertise(s, topic, type, qos_for(op.latch, op.queue_size, None), op.OP, op.id)
    msg = from_json(s.backend.defs, pub.msgdef, op.msg)
    for hook in s.gateway.publish_hooks:
        msg = hook(s, pub, msg)
        if msg is None:
            return
    pub.publisher.publish(msg)


def subscribe(s: ClientSession, op: Subscribe) -> None:
    topic = absolute(op.topic)
    type = _resolve_type(s, topic, op.type, op.OP, op.id)
    existing = s.subscriptions.get(topic)
    if existing is not None and existing.fanout.type != type:
        raise ProtocolError(f'{topic} is already subscribed with type {existing.fanout.type}', op=op.OP, id=op.id)
    fan = s.gateway.fanout(topic, type)
    fresh = s.id not in fan.subscribers
    sub = fan.add(s, op.id, (op.throttle_rate, op.queue_length, op.compression, op.fragment_size))
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
