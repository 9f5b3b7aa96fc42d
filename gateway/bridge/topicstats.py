"""Topic rates and bandwidths, measured by the gateway for the topics a page shows.

``/rosgate/topic_stats`` (rosgate_msgs/srv/TopicStatistics: ``topics`` in; ``rates`` in messages/s,
``bandwidths`` in bytes/s, ``windows`` in s out) measures each topic it is asked about from the
first ask, through the topic's shared subscription (the fan-out), until nobody has asked for
``KEEP`` seconds: the /inspect page asks each second for the rows in view, so a topic is measured
only while someone looks at it, and a list of forty topics costs nothing for the thirty-five
scrolled away.

Why here and not in the page: to count a topic the page would have to receive all of it. The
rover's camera (36 KiB frames at 5 Hz) is 1.4 Mbit/s to a phone that shows one number; here it is
one count and one length per message on the subscription the gateway has anyway (or makes for the
while). A message's size is its CDR's length where the backend hands the CDR over (rclpy, which
takes topics as CDR); otherwise (the sim holds messages as dicts) one message in ``SAMPLE_EVERY``
seconds is serialized to measure it and the others are taken at that size.

The figures cover the last ``WINDOW`` seconds (less while measuring has just begun): the count
and bytes of that span over its length, as ``ros2 topic hz``/``bw`` report them, and a topic that
stops falls to 0 within the window. Callers see only topics they may subscribe to (the access
rule); others, and topics not on the graph, answer -1.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import deque
from typing import TYPE_CHECKING

from ..backends.base import BackendError
from ..rules.access import Action, Name

if TYPE_CHECKING:
    from .fanout import TopicFanout

log = logging.getLogger('rosgate.stats')

SERVICE = '/rosgate/topic_stats'
TYPE = 'rosgate_msgs/srv/TopicStatistics'
WINDOW = 5.0         # s of arrivals the figures cover
KEEP = 4.0           # s a topic stays measured after the last ask
SAMPLE_EVERY = 0.5   # s between serializations of a message to know its size (no CDR at hand)
MAX_TOPICS = 100     # topics one ask may name
MAX_KEPT = 4096      # arrivals kept per topic (a 1 kHz topic: the last 4 s)


class Meter:
    """One topic's arrivals of the last WINDOW seconds: (time, bytes)."""

    __slots__ = ('fan', 'since', 'arrivals', 'bytes', 'size', 'sampled_at', 'asked_at', 'unsized')

    def __init__(self, fan: TopicFanout, now: float):
        self.fan = fan
        self.since = now
        self.arrivals: deque[tuple[float, int]] = deque()
        self.bytes = 0             # the sizes of the arrivals kept, summed as they come and go
        self.size = 0              # the last measured size, for messages that come without CDR
        self.sampled_at = -1e9
        self.asked_at = now
        self.unsized = False       # a message could not be serialized: the bandwidth is unknown

    def count(self, msg: dict, cdr: bytes | None) -> None:
        now = time.monotonic()
        if cdr is not None:
            size = len(cdr)
        else:
            if now - self.sampled_at >= SAMPLE_EVERY:
                self.sampled_at = now
                try:
                    self.size = len(self.fan.gateway.backend.to_cdr(self.fan.type, msg))
                    self.unsized = False
                except Exception:  # noqa: BLE001 (a type the backend cannot serialize: size unknown)
                    self.unsized = True
            size = self.size
        arrivals = self.arrivals
        if len(arrivals) == MAX_KEPT:
            self.bytes -= arrivals.popleft()[1]
        arrivals.append((now, size))
        self.bytes += size

    def read(self, now: float) -> tuple[float, float, float]:
        """(rate, bandwidth, window) over the last WINDOW seconds."""
        start = max(self.since, now - WINDOW)
        arrivals = self.arrivals
        while arrivals and arrivals[0][0] < start:
            self.bytes -= arrivals.popleft()[1]
        span = now - start
        if span <= 0:
            return 0.0, 0.0, 0.0
        if len(arrivals) == MAX_KEPT:   # a fast topic: the window is what is kept
            span = max(now - arrivals[0][0], 1e-3)
        rate = len(arrivals) / span
        bandwidth = -1.0 if self.unsized else self.bytes / span
        return rate, bandwidth, span


class TopicStats:
    """The service and the meters it keeps (one per topic being asked about)."""

    def __init__(self, gateway):
        self.gateway = gateway
        self.meters: dict[str, Meter] = {}
        self._timer: asyncio.TimerHandle | None = None
        gateway.own_service(SERVICE, TYPE, self.answer)

    def answer(self, session, request: dict) -> dict:
        topics = list(request.get('topics') or ())
        if len(topics) > MAX_TOPICS:
            raise BackendError(f'{SERVICE}: at most {MAX_TOPICS} topics at a time, not {len(topics)}')
        now = time.monotonic()
        types = dict(self.gateway.backend.topics(hidden=True))
        rates, bandwidths, windows = [], [], []
        for topic in topics:
            meter = self.meter(session, topic, types.get(topic), now)
            rate, bandwidth, window = meter.read(now) if meter is not None else (-1.0, -1.0, -1.0)
            rates.append(rate)
            bandwidths.append(bandwidth)
            windows.append(window)
        return {'rates': rates, 'bandwidths': bandwidths, 'windows': windows}

    def meter(self, session, topic: str, type: str | None, now: float) -> Meter | None:
        if type is None or session.decide(Action.SUBSCRIBE, Name(topic)) is not None:
            return None
        meter = self.meters.get(topic)
        if meter is None or meter.fan.closed:
            try:
                fan = self.gateway.fanout(topic, type)
            except (BackendError, LookupError) as e:   # a type this gateway cannot subscribe with
                log.info('cannot measure %s: %s', topic, e)
                return None
            meter = self.meters[topic] = Meter(fan, now)
            fan.meter = meter
            self._schedule()
        meter.asked_at = now
        return meter

    def _schedule(self) -> None:
        if self._timer is None and self.meters:
            self._timer = asyncio.get_running_loop().call_later(1.0, self._expire)

    def _expire(self) -> None:
        """Meters nobody asked about for KEEP seconds go, and their subscriptions if nobody else has one."""
        self._timer = None
        now = time.monotonic()
        for topic, meter in list(self.meters.items()):
            if now - meter.asked_at > KEEP or meter.fan.closed:
                del self.meters[topic]
                meter.fan.unmeter(meter)
        self._schedule()
