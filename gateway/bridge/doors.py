"""The doors the bridge opens to the rules: ``RuleDoors``, what ``rules.compose`` hands on to each
part (``rules.ports``), built from the Gateway by the bridge so that no part of the rules holds it.

The Gateway is the ``Announcer`` (its own topics and services), the ``Door`` (the one publish door)
and the ``Parties`` (its sessions and senders); the backend is the graph, the messages' definitions,
the control topic's subscribe and the reset's service call; the hooks take the events; the store is
opened when a part first asks for it (as ``Gateway.store``: a gateway with no rule that keeps
anything opens none).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..rules.hooks import Hooks
from ..rules.ports import Announcer, Door, Parties
from ..store import Store

if TYPE_CHECKING:
    from ..settings import Settings
    from .gateway import Gateway


class RuleDoors:
    """``rules.ports.RuleDoors`` of one Gateway (``Gateway.rule_doors()``)."""

    def __init__(self, gateway: Gateway):
        self.settings: Settings = gateway.settings
        self.backend = gateway.backend
        self.hooks: Hooks = gateway.hooks
        self.announce: Announcer = gateway
        self.door: Door = gateway
        self.parties: Parties = gateway
        self._opened = lambda: gateway.store

    @property
    def store(self) -> Store:
        return self._opened()
