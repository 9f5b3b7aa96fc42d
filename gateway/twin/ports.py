"""What the twin's parts are given (their doors), each the few calls a part makes: typed here, beside them.

``bridge.taps.Taps`` (the topics' shared fan-outs) is the ``Taps``; a backend is the ``Graph`` and
the ``Params`` (both: the ``Backend``); ``rules.policy.Policy`` the ``Names`` (asked through
``rules.access.may``), with its ``auth`` and ``stations`` the ``SignIn``; the fleet of gateways
(``store.fleet.Fleet``) the ``Timekeeper``; ``store.Store`` the ``Store``; ``rules.hooks.Hooks``
hears the history's points (``Points``). No module in twin/ holds the Gateway.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any, Protocol



class Fanout(Protocol):
    """One topic's shared fan-out (``bridge.fanout.TopicFanout``): the history stands in it where a
    client would (``add``/``remove``); a description watches it for the latest message (``last``)."""
    last: dict | None
    subscribers: Any
    def add(self, session: Any, sid: str | None, options: tuple) -> Any: ...
    def remove(self, session: Any, sid: str | None) -> bool: ...
    def watch(self, key: object, callback: Callable[[dict, Any], None]) -> None: ...
    def unwatch(self, key: object) -> None: ...


class Taps(Protocol):
    """The topics' shared fan-outs: a topic's type, its fan-out found or made, one made for nothing
    dropped (no backend subscription left behind)."""
    def topic_type(self, topic: str) -> str | None: ...
    def fanout(self, topic: str, type: str) -> Fanout: ...
    def drop_fanout(self, fan: Any) -> None: ...


class Graph(Protocol):
    """The robot graph's listings (a backend): what the history keeps while something publishes it,
    where a description is found."""
    def topics(self) -> list[tuple[str, str]]: ...
    def publishers(self, topic: str) -> list: ...
    def nodes(self) -> list[str]: ...


class Params(Protocol):
    """A node's parameter (a backend): the robot_state_publisher's description."""
    async def get_param(self, node: str, name: str) -> Any: ...


class Backend(Graph, Params, Protocol):
    """The backend as a robot's description is looked for on it: its listings and a node's parameter."""


class Names(Protocol):
    """The rules' question about a name (``rules.policy.Policy``, asked through ``rules.access.may``),
    and whether a listing shows it."""
    def refusal(self, who: Any, action: str, name: str | None) -> str | None: ...
    def visible(self, session: Any, kind: str, name: str) -> bool: ...


class Tokens(Protocol):
    """The tokens (``auth.tokens.Authenticator``): an OPC UA client's password is one of its user's."""
    def token(self, remote: str, token: str) -> Any: ...


class Stations(Protocol):
    """The stations on a fleet (``rules.stations.Stations``): the OPC UA folders by robot."""
    def stations(self) -> Iterable[str]: ...


class SignIn(Names, Protocol):
    """The policy as the OPC UA server meets it: ``auth`` None when nobody signs in; the stations
    (None: none)."""
    auth: Tokens | None
    stations: Stations | None


class Timekeeper(Protocol):
    """The fleet of gateways on one PostgreSQL (``store.fleet.Fleet``): only its timekeeper writes
    the history, so each series is written once."""
    timekeeper: bool


class Store(Protocol):
    """The one database (``store.Store``): work on its thread."""
    url: str
    sqlite: bool
    def submit(self, fn: Callable) -> Any: ...
    async def run(self, fn: Callable) -> Any: ...
    def size(self) -> int: ...


class Points(Protocol):
    """Where the history tells of each point it keeps (``rules.hooks.Hooks``: ``on_history_point``)."""
    def history_point(self, topic: str, field: str, t: float, v: float) -> None: ...
