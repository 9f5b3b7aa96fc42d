"""What the rules' parts are given (their doors), each the few calls a part makes, typed here.

``bridge.gateway.Gateway`` is an ``Announcer``, a ``Door`` and ``Parties``; a backend is a ``Graph``,
``Messages``, a ``Subscribes`` and a ``Caller``; ``rules.hooks.Hooks`` takes the ``SlotEvents``.
``compose`` hands each part the ones it uses (``bridge.doors.RuleDoors`` brings them all, built by
the bridge): no part of the rules holds the Gateway.
"""

from __future__ import annotations

from collections.abc import Callable, Container, Mapping
from typing import Any, Protocol

from ..backends.base import QoS


class OwnTopic(Protocol):
    """A publisher of the gateway's own announcements (/rosgate/driver, /rosgate/stations)."""
    def publish(self, msg: dict) -> None: ...


class Announcer(Protocol):
    """The gateway's own topics, which clients may not publish to, and the services it answers
    itself, knowing who calls (``answer(session, request) -> response``)."""
    own_services: Container[str]
    def own_topic(self, topic: str, type: str, qos: QoS) -> OwnTopic: ...
    def own_service(self, name: str, type: str, answer: Callable[[Any, dict], Any]) -> None: ...
    def drop_own_service(self, name: str) -> None: ...


class Outlet(Protocol):
    """A shared publisher behind the door (``bridge.gateway.SharedPublisher``)."""
    clients: set[int]
    def attach(self, session_id: int) -> None: ...
    def detach(self, session_id: int) -> None: ...


class Door(Protocol):
    """The one publish door: what the gateway publishes itself (a stop's zero commands) passes the
    rules as the gateway's own (``itself``), on the topic's shared publisher."""
    itself: Any
    publishers: Mapping[str, Outlet]
    def publisher(self, topic: str, type: str, qos: QoS) -> Outlet: ...
    def publish(self, sender: Any, pub: Any, msg: dict, issued: float | None = None, id: str | None = None) -> bool: ...


class Parties(Protocol):
    """Who is there: the client sessions by id (``attrs``, ``status``, ``outbox``), and with the
    open senders that are not clients (playbacks) ``everyone()``."""
    sessions: Mapping[int, Any]
    publishers: Mapping[str, Outlet]    # who advertises what (a station in use)
    def everyone(self) -> list: ...


class Graph(Protocol):
    """The robot graph's listings (a backend)."""
    def topics(self) -> list[tuple[str, str]]: ...
    def subscribers(self, topic: str) -> list[str]: ...


class Messages(Protocol):
    """Message definitions and ROS time (a backend): a zero command made to measure."""
    defs: Any
    def msg_def(self, type: str) -> Any: ...
    def now(self) -> tuple[int, int]: ...


class Subscribes(Protocol):
    """The backend's subscribe (the control topic declared, so clients publish to it untyped)."""
    def subscribe(self, topic: str, type: str, callback: Callable[[dict], None]) -> Any: ...


class Caller(Protocol):
    """The backend's services, called as the gateway (a slot's --station-reset)."""
    def services(self) -> list[tuple[str, str]]: ...
    async def call_service(self, service: str, type: str, request: dict, timeout: float) -> dict: ...


class SlotEvents(Protocol):
    """Where a slot's end is told (``rules.hooks.Hooks``: ``on_slot_ended`` of every part)."""
    def slot_ended(self, station: str, person: str, why: str) -> None: ...


class TimetableEvents(Protocol):
    """Where a booking made or removed is told (``rules.hooks.Hooks``: ``on_timetable_changed``)."""
    def timetable_changed(self) -> None: ...


class LeaseView(Protocol):
    """The driver lease as the stations meet it (``rules.lease.Lease``): built after them, since it
    asks them who owns what, so the stations are given ``() -> the lease`` (None: no lease)."""
    holders: Mapping[str, Any]
    def elsewhere(self, group: str, key: str) -> str | None: ...
    def free(self, group: str, by: Any) -> None: ...
    def released_elsewhere(self, group: str, by: str) -> None: ...


class Backend(Graph, Messages, Subscribes, Caller, Protocol):
    """The backend as the rules use it: its graph, definitions and clock, subscribe and service call."""


class GroupEvents(SlotEvents, TimetableEvents, Protocol):
    """The events the rules emit (``rules.hooks.Hooks``): a group stopped, a slot ended, the
    timetable changed, a sign-in ended."""
    def group_stopped(self, group: str, group_of: Callable[[str], str]) -> None: ...
    def signed_out(self, key: str) -> None: ...


class RuleDoors(Protocol):
    """Everything ``compose`` hands on, in one value (``bridge.doors.RuleDoors``, built by the bridge):
    the settings, the store (opened when first asked for), the backend, the hooks, and the gateway's
    own topics and services, its publish door and who is there, and the part closing an ended
    sign-in's websockets (a ``rules.hooks.Hook``, heard with the rules' parts when there are sign-ins)."""
    settings: Any
    store: Any
    backend: Backend
    hooks: GroupEvents
    announce: Announcer
    door: Door
    parties: Parties
    signouts: Any
