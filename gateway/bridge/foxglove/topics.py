"""Foxglove's subscribe and unsubscribe (server channels, through the shared fan-out) and a
client's advertise, unadvertise and message data (its channels, through the one publish door).

A subscription is one more subscriber of the topic's fan-out, with the encoding ``cdr``: the
fan-out makes each message's CDR once (the rclpy backend hands over the bytes it took; the sim's
dict is serialized) for every Foxglove subscriber, and each subscriber's ``Feed`` puts its own
13-byte header in front. A client's message is read from its encoding (``cdr`` by the backend,
``json`` by rosbridge's JSON rules) into a message dict and published by ``Gateway.publish`` as
the client, like a rosbridge ``publish``: lease, clamps and fresh commands apply, and the stop on
disconnect knows what it left moving.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from protocol import foxglove as fg
from protocol import ops
from protocol.codec import decode_text
from protocol.convert import from_json
from protocol.errors import ProtocolError

from ...backends.base import QoS

if TYPE_CHECKING:
    from .session import FoxgloveSession

OPTIONS = (0, 0, 'cdr', None, None)   # fan-out options: no throttle, the default queue, the CDR alone
NO_MESSAGE: dict = {}                 # a publish op's message, as the policy's gate sees it (unread)


class Dropped(Exception):
    """The policy dropped an op without a word (a client already being disconnected)."""


class Feed:
    """Where one Foxglove subscription stands in a topic's fan-out (as a recording's tap does):
    each message's CDR gets this subscription's header (its id, when the gateway took it:
    ``hub.Framer``) and goes to the session's outbox as a topic message, which the outbox drops for
    a slow client."""

    __slots__ = ('session', 'id', 'sub_id', 'outbox')

    def __init__(self, session: FoxgloveSession, sub_id: int):
        self.session, self.id, self.sub_id = session, session.id, sub_id
        self.outbox = self

    @property
    def closed(self) -> bool:
        return self.session.closed

    def message(self, frame: bytes, binary: bool, key: object, queue_length: int) -> bool:
        session = self.session
        return session.outbox.message(session.hub.framer.frame(self.sub_id, frame), True, key, queue_length)

    def forget(self, key: object) -> None:
        self.session.outbox.forget(key)


@dataclass(frozen=True, slots=True)
class Outgoing:
    """A client's channel: where its messages go and how they are written."""
    topic: str
    type: str
    encoding: str
    pub: Any   # bridge.gateway.SharedPublisher
    op: ops.Publish   # each message as the policy's gate sees it (made once: it never changes)


def _each(s: FoxgloveSession, op, items, one, ident) -> None:
    """``one(s, item)`` for each item of an op; a refused item is reported with its id and the
    others go on."""
    for item in items:
        try:
            one(s, item)
        except Dropped:
            raise
        except Exception as e:   # noqa: BLE001 (reported as the catch site would, item by item)
            s.report(op.OP, str(ident(item)), e)


def subscribe(s: FoxgloveSession, op: fg.Subscribe) -> None:
    _each(s, op, op.subscriptions, _subscribe, lambda sub: sub.id)


def _subscribe(s: FoxgloveSession, sub: fg.Subscription) -> None:
    if sub.id in s.subs:
        raise ProtocolError(f'subscription id {sub.id} is in use (unsubscribe it first)')
    channel = s.hub.channel_ids.get(sub.channel_id) if sub.channel_id in s.channels else None
    if channel is None:
        raise ProtocolError(f'channel {sub.channel_id} is not advertised to this client')
    if channel.topic in s.subscriptions:
        raise ProtocolError(f'channel {sub.channel_id} ({channel.topic}) is already subscribed by this client')
    s.admit(ops.Subscribe(topic=channel.topic, id=str(sub.id), type=channel.type))
    if channel.topic not in s.gateway.fanouts:   # a type the backend cannot serialize fails here, not in the fan-out
        s.backend.to_cdr(channel.type, {})
    fan = s.gateway.fanout(channel.topic, channel.type)
    try:
        added = fan.add(Feed(s, sub.id), None, OPTIONS)
    except BaseException:   # release next to creation: a failed subscribe leaves no subscription
        if not fan.subscribers and not fan.watchers:
            s.gateway.drop_fanout(fan)
        raise
    s.subscriptions[channel.topic] = added
    s.subs[sub.id] = channel.topic
    fan.replay_latched(added)


def unsubscribe(s: FoxgloveSession, op: fg.Unsubscribe) -> None:
    s.gate(op.OP)
    for sid in op.subscription_ids:
        if not s.drop_subscription(sid):
            s.status('warning', f'subscription id {sid} is not subscribed', op.OP)


def advertise(s: FoxgloveSession, op: fg.Advertise) -> None:
    _each(s, op, op.channels, _advertise, lambda channel: channel.id)


def _advertise(s: FoxgloveSession, channel: fg.ClientChannel) -> None:
    if channel.id in s.client_channels:
        raise ProtocolError(f'channel {channel.id} is already advertised by this client (unadvertise it first)')
    limit = s.gateway.settings.security.max_publishers
    if len(s.client_channels) >= limit:
        raise ProtocolError(f'this client already has {limit} channels (--max-publishers)')
    if channel.encoding not in fg.ENCODINGS:
        raise ProtocolError(f'encoding {channel.encoding!r} is not supported: publish in {" or ".join(fg.ENCODINGS)}')
    topic = channel.topic if channel.topic.startswith('/') else '/' + channel.topic
    type = s.backend.msg_def(channel.schema_name).type   # unknown types fail here, naming the type
    s.admit(ops.Advertise(topic=topic, type=type, id=str(channel.id)))
    pub = s.publishers.get(topic)
    if pub is None:
        pub = s.gateway.publisher(topic, type, QoS())
        pub.attach(s.id)
        s.publishers[topic] = pub
    elif pub.type != type:
        raise ProtocolError(f'{topic} is already advertised by this client with type {pub.type}')
    s.client_channels[channel.id] = Outgoing(topic, type, channel.encoding, pub,
                                             ops.Publish(topic=topic, msg=NO_MESSAGE, id=str(channel.id), type=type))


def unadvertise(s: FoxgloveSession, op: fg.Unadvertise) -> None:
    s.gate(op.OP)
    for cid in op.channel_ids:
        gone = s.client_channels.pop(cid, None)
        if gone is None:
            s.status('warning', f'channel {cid} is not advertised by this client', op.OP)
        elif not any(c.topic == gone.topic for c in s.client_channels.values()):
            s.publishers.pop(gone.topic).detach(s.id)


def message_data(s: FoxgloveSession, op: fg.MessageData) -> None:
    channel = s.client_channels.get(op.channel_id)
    if channel is None:
        raise ProtocolError(f'channel {op.channel_id} is not advertised by this client (advertise it first)',
                            id=str(op.channel_id))
    s.admit(channel.op)
    if channel.encoding == 'cdr':
        msg = s.backend.from_cdr(channel.type, op.data)
    else:
        msg = from_json(s.backend.defs, channel.pub.msgdef, decode_text(op.data))
    s.gateway.publish(s, channel.pub, msg)


TOPICS = {
    fg.Subscribe: subscribe,
    fg.Unsubscribe: unsubscribe,
    fg.Advertise: advertise,
    fg.Unadvertise: unadvertise,
    fg.MessageData: message_data,
}
