"""A Foxglove client's session: a ``ClientSession`` whose frames are the Foxglove protocol's.

Everything that keeps a robot safe is the rosbridge session's, unchanged, because it is one: the
sign-in at connect (a token in the URL's query, or the session cookie of /login; a Foxglove client
has no auth op, so an unsigned client under --auth is told so and closed after --auth-timeout), the
policy's gate in front of every op (rate, sign-in, names, role, caps, the lease for calls), the
ops' guards, the one publish door (lease, clamps, fresh commands: an unstamped command after a
stop waits for the pong of the gateway's ping, which browsers and ``ws`` answer by themselves),
the bounded outbox (topic messages dropped for a slow client, per subscription, with a warning;
replies never), and ``close``: every subscription, publisher and call released, and the hooks
told, so the stop on disconnect zeroes what the client left moving.

Each Foxglove op that names a topic or service asks the policy as the rosbridge op that does the
same would (``admit``): a subscription as ``subscribe``, a client channel as ``advertise``, each of
its messages as ``publish``, a service call as ``call_service``; the others (parameters, the
graph) as an op that names nothing (rate and sign-in), then the access rule for what they read or
change. Errors become Foxglove ``status`` messages naming the op (and the id it concerns); a
refused or failed service call its ``serviceCallFailure``; the connection carries on.
"""

from __future__ import annotations

import asyncio
import logging
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from protocol import foxglove as fg
from protocol.errors import ProtocolError

from ...rules.access import Action, Name
from ..session import ClientSession
from .calls import CALLS
from .hub import EMPTY, Channel, Graph, Service
from .topics import TOPICS, Dropped

if TYPE_CHECKING:
    from ..gateway import Gateway

log = logging.getLogger('rosgate.foxglove')


@dataclass(frozen=True, slots=True)
class Gate:
    """An op that names no topic or service, as the policy's gate sees it (its rate, the sign-in)."""
    OP: str
    id: str | None = None


class FoxgloveSession(ClientSession):
    def __init__(self, gateway: Gateway, *args, subprotocol: str = fg.WEBSOCKET_V1, **kwargs):
        super().__init__(gateway, *args, **kwargs)
        self.subprotocol = subprotocol
        self.hub = gateway.foxglove
        self.subs: dict[int, str] = {}                  # subscription id -> topic
        self.channels: set[int] = set()                 # server channels advertised to this client
        self.offered_services: set[int] = set()
        self.client_channels: dict[int, Any] = {}       # the client's channel id -> topics.Outgoing
        self.param_subs: set[str] = set()               # '/node.param' the client follows
        self.graph: Graph | None = None                 # the connection graph as last sent, while followed
        self._advertised = False

    def open(self) -> None:
        super().open()
        backend = self.gateway.backend
        # ROS_DISTRO: Lichtblick and Foxglove read it to treat the data as ROS 2 (both backends speak Jazzy)
        self.send(fg.server_info(f'rosgate ({backend.name})', fg.CAPABILITIES, self.hub.session_id,
                                 {'ROS_DISTRO': os.environ.get('ROS_DISTRO') or 'jazzy', 'backend': backend.name}))
        if not self.gateway.policy.signed_in(self):
            reason = self.attrs.get('auth_error')
            self.status('error', 'not authenticated: connect with ?token=... in the URL (or sign in at /login '
                        f'in this browser first){f" (the token given: {reason})" if reason else ""}; '
                        'this gateway shows nothing and takes nothing without it')
        self.hub.join(self)

    # --- incoming ------------------------------------------------------------------------------

    def receive(self, data: str | bytes, text: bool | None = None) -> None:
        if self.closed or self.closing:
            return
        self.clock.heard(asyncio.get_running_loop().time())
        if text is None:
            text = not isinstance(data, bytes)
        limit = self.gateway.settings.max_message_size
        if limit is not None and len(data) > limit:
            self.status('error', f'message of {len(data)} bytes exceeds max_message_size {limit}')
            return
        try:
            op = fg.parse_text(data) if text else fg.parse_binary(data)
        except ProtocolError as e:
            self.report(e.op, e.id, e)
            return
        except Exception as e:   # a bug in decoding: the frame is lost, the connection is not
            self.report(None, None, e)
            return
        try:
            HANDLERS[type(op)](self, op)
        except Dropped:
            pass
        except Exception as e:  # the one catch site: every failure becomes a status
            self.report(op.OP, getattr(op, 'id', None), e)

    def admit(self, op) -> None:
        """The rules in front of a client's op, as for a rosbridge client's (``op`` is the rosbridge
        op that would do the same, or a ``Gate``): raises ProtocolError to refuse it, Dropped to
        drop it without a word."""
        if self.gateway.policy.admit(self, op) is False:
            raise Dropped
        for guard in self.gateway.guards:
            guard(self, op)

    def gate(self, op: str, id: str | None = None, work: bool = False) -> None:
        """``admit`` for an op that names no topic or service: its rate and the sign-in; ``work``:
        it starts a task (parameters), which counts against --max-pending-calls as calls do."""
        self.admit(Gate(op, id))
        limit = self.gateway.settings.security.max_pending_calls
        if work and len(self.tasks) >= limit:
            raise ProtocolError(f'this client already has {limit} calls and requests pending (--max-pending-calls)',
                                op=op, id=id)

    def may(self, action: Action, name: str | None) -> bool:
        return self.decide(action, Name(name)) is None

    # --- outgoing ------------------------------------------------------------------------------

    def send(self, frame: bytes, binary: bool = False) -> None:
        """A message that is not a topic's (never dropped)."""
        if not self.closed:
            self.outbox.reply(frame, binary)

    def status(self, level: str, msg: str, op: str | None = None, id: str | None = None) -> None:
        if op and not msg.startswith((f'{op}:', f'{op} ')):
            msg = f'{op}{f" (id {id})" if id is not None else ""}: {msg}'
        self.send(fg.status(level, msg))

    def reply(self, op: dict, *args, **kwargs) -> None:
        """A rosbridge reply has no Foxglove form. The rules send one only with a refusal (the
        failed service_response of a refused call), which reaches this client as the refusal's
        own ProtocolError: a serviceCallFailure or a status."""
        log.debug('foxglove client %s: rosbridge reply %s not sent', self.id, op.get('op'))

    def _overflow(self, dropped: int) -> None:
        self.status('warning', f'client is not reading fast enough: dropped {dropped} topic messages '
                               f'(send buffer over {self.outbox.byte_limit} bytes)')

    # --- what the hub tells ----------------------------------------------------------------------

    def offer(self, added: list[Channel], removed: list[Channel], s_added: list[Service],
              s_removed: list[Service]) -> None:
        """Channels and services that appeared or went; those this client may use are advertised
        (the first time, an advertise message even when empty, as the protocol wants)."""
        gone = [c.id for c in removed if c.id in self.channels]
        for channel in removed:
            if channel.id in self.channels:
                for sid, topic in list(self.subs.items()):
                    if topic == channel.topic:
                        self.drop_subscription(sid)
        self.channels.difference_update(gone)
        new = [c for c in added if self.may(Action.SUBSCRIBE, c.topic)]
        self.channels.update(c.id for c in new)
        if gone:
            self.send(fg.unadvertise(gone))
        if new or not self._advertised:
            self._advertised = True
            self.send(fg.advertise([c.wire for c in new]))
        s_gone = [s.id for s in s_removed if s.id in self.offered_services]
        self.offered_services.difference_update(s_gone)
        s_new = [s for s in s_added if self.may(Action.CALL, s.name)]
        self.offered_services.update(s.id for s in s_new)
        if s_gone:
            self.send(fg.unadvertise_services(s_gone))
        if s_new:
            self.send(fg.advertise_services([s.wire for s in s_new]))

    def drop_subscription(self, sid: int) -> bool:
        """End subscription ``sid`` (False if there is none)."""
        topic = self.subs.pop(sid, None)
        if topic is None:
            return False
        sub = self.subscriptions.pop(topic, None)
        if sub is not None:
            sub.fanout.remove(self, None)
        return True

    def graph_changed(self, graph: Graph) -> None:
        """The names this client may see whose nodes changed since it was last told, and those
        that went."""
        last = self.graph or EMPTY
        published = {t: n for t, n in graph.published.items() if self.listed('topics', t)}
        subscribed = {t: n for t, n in graph.subscribed.items() if t in published}
        services = {s: n for s, n in graph.services.items() if self.listed('services', s)}
        update = ({t: n for t, n in published.items() if last.published.get(t) != n},
                  {t: n for t, n in subscribed.items() if last.subscribed.get(t) != n},
                  {s: n for s, n in services.items() if last.services.get(s) != n},
                  [t for t in last.published if t not in published], [s for s in last.services if s not in services])
        self.graph = Graph(published, subscribed, services)
        if any(update):
            self.send(fg.connection_graph_update(*update))

    # --- teardown ------------------------------------------------------------------------------

    def close(self) -> None:
        if self.closed:
            return
        self.hub.leave(self)
        self.subs.clear()
        self.client_channels.clear()
        self.param_subs.clear()
        super().close()   # subscriptions, publishers, calls released; the hooks told (stop on disconnect)


def choose_subprotocol(offered: list[str]) -> str | None:
    """What a websocket upgrade answers: a Foxglove subprotocol the client offers, else None (the
    rosbridge protocol, which clients ask for with no subprotocol or one of their own)."""
    return fg.choose(offered)


def session_for(subprotocol: str | None, gateway: Gateway, *args, **kwargs) -> ClientSession:
    """The one choice of protocol: a Foxglove session for a Foxglove subprotocol, a rosbridge
    session for anything else; ``args`` as ``ClientSession`` takes them."""
    if subprotocol in fg.SUBPROTOCOLS:
        return FoxgloveSession(gateway, *args, subprotocol=subprotocol, **kwargs)
    return ClientSession(gateway, *args, **kwargs)


HANDLERS = {**TOPICS, **CALLS}
