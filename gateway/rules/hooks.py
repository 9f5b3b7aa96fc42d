"""Hooks: the events of the gateway's life that its parts follow, named in one interface.

A part (the lease, safety, stations, slots, runs, recordings, history, the OPC UA twin, the
exercises' checker and grades, the bridge's sign-outs) subclasses ``Hook`` and overrides the events
it takes; ``Hooks`` calls every part, in the order given to ``seal`` (once, by ``server.start``,
when every part is built), for each event. This is the one way a part hears of another's events:
no part keeps a list of callbacks or a callable slot for another to fill (``tests/gateway/
test_layers.py`` checks it). A part that emits is given the ``Hooks`` at construction and calls its
emitter (``hooks.slot_ended(...)``), never another part. Dispatch is here alone: a part that raises
is logged with the event's name and the others still hear it (a failing recording must not keep a
run from being stopped at a slot's end), and an ``on_shutdown`` that returns an awaitable is awaited
before the next part's. An event emitted before ``seal`` is heard by nobody (nothing is running yet).
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

    def on_timetable_changed(self) -> None:
        """A booking was made or removed (here, or read from another gateway of the fleet)."""

    def on_signed_out(self, key: str) -> None:
        """A sign-in ended (here or on another gateway): ``key`` names it (``auth.sessions``)."""

    def on_attempt_ended(self, identity, exercise, result) -> None:
        """An exercise attempt ended, passed or failed (``exercises.checker``)."""

    def on_history_point(self, topic: str, field: str, t: float, v: float) -> None:
        """The history kept a new point of a topic's numeric field (``twin.history``)."""

    def on_shutdown(self) -> Awaitable | None:
        """The gateway is stopping, while publishers and clients still exist."""


class Hooks:
    """The parts, in order, and the one place that calls them."""

    def __init__(self) -> None:
        self._parts: tuple[Hook, ...] = ()
        self.sealed = False

    def seal(self, parts) -> None:
        """Every part, in the order they hear each event: once, when all are built."""
        if self.sealed:
            raise RuntimeError('the hooks are sealed once')
        parts = tuple(p for p in parts if p is not None)
        for part in parts:
            if not isinstance(part, Hook):
                raise TypeError(f'{type(part).__name__} is not a Hook')
        self._parts, self.sealed = parts, True

    def __iter__(self) -> Iterator[Hook]:
        return iter(self._parts)

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

    def timetable_changed(self) -> None:
        self._emit('on_timetable_changed')

    def signed_out(self, key: str) -> None:
        self._emit('on_signed_out', key)

    def attempt_ended(self, identity, exercise, result) -> None:
        self._emit('on_attempt_ended', identity, exercise, result)

    def history_point(self, topic: str, field: str, t: float, v: float) -> None:
        self._emit('on_history_point', topic, field, t, v)

    async def shutdown(self) -> None:
        for part in self:
            try:
                result = part.on_shutdown()
                if inspect.isawaitable(result):
                    await result
            except Exception:
                log.exception('on_shutdown hook of %s failed', type(part).__name__)
