"""The doors the bridge opens to the rules: ``RuleDoors``, what ``rules.compose`` hands on to each
part (``rules.ports``), built from the Gateway by the bridge so that no part of the rules holds it.

The Gateway is the ``Announcer`` (its own topics and services), the ``Door`` (the one publish door)
and the ``Parties`` (its sessions and senders); the backend is the graph, the messages' definitions,
the control topic's subscribe and the reset's service call; the hooks take the events (and
``SignOuts``, a part the rules put among their hooks with sign-ins, closes an ended sign-in's
websockets); the store is
opened when a part first asks for it (as ``Gateway.store``: a gateway with no rule that keeps
anything opens none).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..rules.hooks import Hook, Hooks
from ..rules.ports import Announcer, Door, Parties
from ..store import Store

if TYPE_CHECKING:
    from ..settings import Settings
    from .gateway import Gateway


class SignOuts(Hook):
    """A sign-in ended (``auth.sessions``, here or on another gateway of the fleet): its websockets
    close (1008), on this gateway."""

    def __init__(self, gateway: Gateway):
        self._sessions = gateway.sessions

    def on_signed_out(self, key: str) -> None:
        for session in list(self._sessions.values()):
            if session.attrs.get('signin') == key:
                session.close_connection(1008, 'signed out')


class RuleDoors:
    """``rules.ports.RuleDoors`` of one Gateway (``Gateway.rule_doors()``)."""

    def __init__(self, gateway: Gateway):
        self.settings: Settings = gateway.settings
        self.backend = gateway.backend
        self.hooks: Hooks = gateway.hooks
        self.announce: Announcer = gateway
        self.door: Door = gateway
        self.parties: Parties = gateway
        self.signouts: Hook = SignOuts(gateway)
        self._opened = lambda: gateway.store

    @property
    def store(self) -> Store:
        return self._opened()
