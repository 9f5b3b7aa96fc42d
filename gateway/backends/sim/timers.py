"""The sim graph's timers: every timer of one period runs from one loop callback (``Ticker``)."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .graph import Graph, Node

log = logging.getLogger('rosgate.sim')


class SimTimer:
    __slots__ = ('ticker', 'node', 'callback')

    def __init__(self, ticker: Ticker, node: Node, callback: Callable[[], Any]):
        self.ticker, self.node, self.callback = ticker, node, callback

    def run(self) -> None:
        try:
            self.callback()
        except Exception:
            log.exception('timer of %s failed', self.node.name)

    def cancel(self) -> None:
        self.ticker.timers.pop(self, None)
        self.node._timers.discard(self)


class Ticker:
    """Every timer of one period, run by one loop callback inside the graph's ``batch_scope``.

    Thirty stations' robots tick at 62.5 Hz: as a task each (an ``asyncio.sleep`` per tick), the
    timers alone cost a task wake-up and a timer handle 1,875 times a second; here they cost one
    callback per period, and what the tick publishes for one client leaves in one socket write
    (the gateway's ``corked``). A timer added later runs once at once and joins the ticker's phase.
    """

    def __init__(self, graph: Graph, period: float):
        self.graph, self.period = graph, period
        self.timers: dict[SimTimer, None] = {}   # in the order they were added
        self.next_at: float | None = None
        self.handle: asyncio.TimerHandle | None = None

    def add(self, node: Node, callback: Callable[[], Any]) -> SimTimer:
        timer = SimTimer(self, node, callback)
        self.timers[timer] = None
        loop = asyncio.get_running_loop()
        loop.call_soon(self._first, timer)
        if self.handle is None:
            self.next_at = loop.time() + self.period
            self.handle = loop.call_at(self.next_at, self._fire)
        return timer

    def _first(self, timer: SimTimer) -> None:
        if timer in self.timers:
            with self.graph.batch_scope():
                timer.run()

    def _fire(self) -> None:
        self.handle = None
        if not self.timers:
            self.graph._tickers.pop(self.period, None)
            return
        with self.graph.batch_scope():
            for timer in list(self.timers):
                timer.run()
        self.next_at += self.period   # a loop behind catches up, as a timer of its own would
        self.handle = asyncio.get_running_loop().call_at(self.next_at, self._fire)
