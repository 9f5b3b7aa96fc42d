"""What the media parts are given (their doors), each the few calls a part makes: typed here, beside them.

``bridge.taps.Taps`` (the topics' shared fan-outs) is the ``Taps``, ``bridge.taps.Senders`` (the one
publish door, for someone who is not a client) the ``Senders``; a backend is the ``Graph`` and the
``Types``; ``rules.policy.Policy`` the ``Names`` (asked through ``rules.access.may``), with its lease; the
parts themselves are sealed into ``rules.hooks.Hooks`` by ``server.start``. No module in media/ holds the Gateway.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from ..backends.base import QoS
from .images import ImageError, Target


class Fanout(Protocol):
    """One topic's shared fan-out (``bridge.fanout.TopicFanout``): a recorder stands in it where a
    client would (``add``/``remove``, its latched messages replayed), a stream watches it."""
    def add(self, session: Any, sid: str | None, options: tuple) -> Any: ...
    def remove(self, session: Any, sid: str | None) -> bool: ...
    def replay_latched(self, sub: Any) -> None: ...
    def watch(self, key: object, callback: Callable[[dict, bytes | ImageError | None], None],
              target: Target | None = None) -> None: ...
    def unwatch(self, key: object) -> None: ...


class Taps(Protocol):
    """The topics' shared fan-outs, found or made (one backend subscription for every reader)."""
    def fanout(self, topic: str, type: str) -> Fanout: ...


class Graph(Protocol):
    """The robot graph's topics (a backend): what a recording's globs match, what a stream finds."""
    def topics(self) -> list[tuple[str, str]]: ...


class Types(Protocol):
    """Message definitions (a backend): what a recording writes beside its messages."""
    def msg_def(self, type: str) -> Any: ...
    def full_text(self, msgdef: Any) -> str: ...
    def to_cdr(self, type: str, msg: dict) -> bytes: ...


class Outlet(Protocol):
    """A shared publisher behind the door (``bridge.gateway.SharedPublisher``)."""
    def detach(self, session_id: int) -> None: ...


class Senders(Protocol):
    """Publishing for a person who is not a client (a playback), through the one publish door: the
    name globs, the lease, clamps and stops apply as to that person's own ops. ``probe``: a sender
    never opened, to ask the rules about before anything is published."""
    def open_sender(self, name: str, role: str | None, remote: str = '', person: str | None = None) -> Any: ...
    def open_publisher(self, sender: Any, topic: str, type: str, qos: QoS) -> Outlet: ...
    def publish(self, sender: Any, pub: Any, msg: dict) -> bool: ...
    def close_sender(self, sender: Any) -> None: ...
    def probe(self, name: str, role: str | None, person: str | None = None) -> Any: ...


class StationNames(Protocol):
    """A station's other names: its holder's (``rules.stationnames.StationNames``)."""
    def refusal(self, asker: Any, name: str) -> str | None: ...


class Lease(Protocol):
    """The driver lease (``rules.lease.Lease``), as a playback meets it."""
    names: StationNames
    def is_command(self, name: str, type: str | None = None) -> bool: ...
    def topic_refusal(self, key: str | None, topic: str, type: str | None) -> str | None: ...


class Names(Protocol):
    """The rules' question about a name (``rules.policy.Policy``, asked through ``rules.access.may``)
    and the lease with --exclusive-control (else None)."""
    lease: Lease | None
    def refusal(self, who: Any, action: str, name: str | None) -> str | None: ...

