"""What the run manager is given (its doors), each the few calls it makes: typed here, beside it.

``bridge.gateway.Gateway`` is an ``Announcer``, a backend a ``Graph``, ``rules.Rules`` an ``InForce``
(its ``lease`` a ``LeaseView``, its ``safety`` the ``Stops``); the manager never holds the Gateway.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Any, Protocol

from ..backends.base import QoS


class OwnTopic(Protocol):
    """A publisher of the gateway's own (a run's output or state): clients may not publish there."""
    def publish(self, msg: dict) -> None: ...
    def destroy(self) -> None: ...


class Announcer(Protocol):
    """The gateway's own topics (``Gateway.own_topic``)."""
    def own_topic(self, topic: str, type: str, qos: QoS) -> OwnTopic: ...


class Graph(Protocol):
    """The robot graph's listings (a backend): the namespaces a run may have, the names it may record."""
    def nodes(self) -> list[str]: ...
    def topics(self) -> list[tuple[str, str]]: ...


class LeaseView(Protocol):
    """The driver lease (``rules.lease.Lease``), as a run meets it."""
    def run_refusal(self, key: str, role: str | None, ns: str) -> str | None: ...
    def take(self, session: Any, ns: str | None = None) -> None: ...


class Stops(Protocol):
    """The safety's stops (``rules.safety.Safety``): a stopped run's commands zeroed."""
    types: Collection[str]
    def stop_session(self, session: Any, where: Callable[[str], bool] | None = None) -> int: ...


class SignIn(Protocol):
    """The policy's sign-in (``rules.policy``): ``auth`` None when nobody signs in."""
    auth: Any


class InForce(Protocol):
    """The rules in force (``rules.Rules``): composed after the manager, which they hold at the
    publish door, so read when a run needs them (``RunManager(rules=...)``)."""
    lease: LeaseView | None
    safety: Stops
    policy: SignIn
