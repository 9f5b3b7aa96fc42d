"""Hooks: the events of the gateway's life that its parts follow, named in one interface.

A part (the lease, safety, stations, slots, runs, recordings, history, the OPC UA twin) subclasses
``Hook`` and overrides the events it takes; ``Hooks`` calls every part added, in the order added,
for each event. Dispatch is here alone: a part that raises is logged with the event's name and the
others still hear it (a failing recording must not keep a run from being stopped at a slot's end),
and an ``on_shutdown`` that returns an awaitable is awaited before the next part's.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Awaitable, Callable, Iterator

log = logging.getLogger('rosgate')


class Hook:
    """Every event, each a no-op here (the foxglove_bridge server-handlers shape)."""

    def on_connect(self, session, request) -> None:
        """A websocket client has connected (its session and the HTTP upgrade request)."""

    def on_close(self, who) -> None:
        """A client session or a sender (a playback, a run) is gone."""

    def on_group_stopped(self, group: str, group_of: Callable[[str], str]) -> None:
        """The teacher's Stop or a slot's end zeroed a group's commands; ``group_of(topic)`` names
        a topic's group."""

    def on_slot_ended(self, station: str, person: str, why: str) -> None:
        """A booked slot on ``station`` ended (``why``: 'ended', 'cancelled' ...)."""

    def on_shutdown(self) -> Awaitable | None:
        """The gateway is stopping, while publishers and clients still exist."""


class Hooks:
    """The parts, in order, and the one place that calls them."""

    def __init__(self) -> None:
        self._parts: list[Hook] = []

    def add(self, part: Hook) -> None:
        if not isinstance(part, Hook):
            raise TypeError(f'{type(part).__name__} is not a Hook')
        self._parts.append(part)

    def __iter__(self) -> Iterator[Hook]:
        return iter(list(self._parts))

    def __len__(self) -> int:
        return len(self._parts)

    def _emit(self, event: str, *args) -> None:
        for part in self:
            try:
                getattr(part, event)(*args)
            except Exception:
                log.exception('%s hook of %s failed', event, type(part).__name__)

    def connect(self, session, request) -> None:
        self._emit('on_connect', session, request)

    def close(self, who) -> None:
        self._emit('on_close', who)

    def group_stopped(self, group: str, group_of: Callable[[str], str]) -> None:
        self._emit('on_group_stopped', group, group_of)

    def slot_ended(self, station: str, person: str, why: str) -> None:
        self._emit('on_slot_ended', station, person, why)

    async def shutdown(self) -> None:
        for part in self:
            try:
                result = part.on_shutdown()
                if inspect.isawaitable(result):
                    await result
            except Exception:
                log.exception('on_shutdown hook of %s failed', type(part).__name__)
