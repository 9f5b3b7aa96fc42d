"""When a client made its command: the clock of each connection, from the stamps it sends.

A link that stalls (a home line's outage, a WiFi roam) holds what the client sent in TCP's
buffers; when it returns, every queued command arrives at once and, applied, would drive the robot
after its operator let go (measured over an emulated home link: a 2 s freeze replayed 14 to 15
commands that moved the turtle 0.16 to 0.30 m more). The gateway cannot tell a replayed command
from a fresh one by arrival alone, so a client may stamp its ops: ``"t"``, its own clock in
milliseconds when it made the op (any clock that does not jump over the connection; the pages use
``performance.now()``), on ``publish`` and on the ``ping`` op (docs/protocol.md).

The client's clock and the gateway's are unrelated, so the gateway keeps for each connection the
smallest ``arrival - t`` it has seen (``base``): the offset between the two clocks plus the fastest
trip seen. ``issued(t) = t + base`` is then when the op would have arrived over that fastest path,
and ``arrival - issued`` its delay beyond it: the time it waited in a queue, a retransmission or
a stalled link. The base may rise only ``DRIFT`` (1 ms per second) between samples, so it follows
two clocks that drift apart without a stall being mistaken for one. Pings every fraction of a
second (the pages') keep it fresh before the first command.

A client that does not stamp (roslibpy, roslibjs's ``Topic.publish``, any plain rosbridge client)
gets the coarser rule of ``Fence``: when the gateway stops its stream it sends that connection a
websocket ping, and drops its moving commands until the pong comes back. TCP keeps the order of
what the client sends, so every command it sent before it read the ping (a stalled link's backlog
among them) arrives before the pong; browsers and client libraries answer pings by themselves.

A link that stalls and comes back may deliver its backlog sooner than ``cmd_max_age`` after the
last commands of the stall were made, so age alone would let those through. A client that pings
(the pages, every 250 ms) is never silent for long while its link works; when a frame from it
arrives after more than ``STALL`` of silence, the link has stalled until then (``stall_end``), and
a command made before that moment was made during the stall: it is part of the backlog. (A fresh
command that happens to end a stall may be dropped with it: one command, on the safe side.)
"""

from __future__ import annotations

import math

DRIFT = 0.001       # s per s the base may rise: far above any two clocks' drift, far below a stall's delay
STALL = 0.5         # s of silence from a client that pings: its link stalled
STALL_SLACK = 0.02  # s: a command made this close before the stall's end counts as fresh (clock grain)


class ClientClock:
    """One connection's clock offset, from its stamped ops."""

    __slots__ = ('base', 'at', 'pinging', 'last_heard', 'stall_end')

    def __init__(self) -> None:
        self.base: float | None = None   # smallest (arrival - t) seen, with drift allowed
        self.at = 0.0                    # when base was last updated
        self.pinging = False             # the client pings: its silence means a stalled link
        self.last_heard: float | None = None
        self.stall_end = -math.inf       # when its link last came back from a stall

    def heard(self, now: float) -> None:
        """A frame arrived from the client (any op)."""
        if self.pinging and self.last_heard is not None and now - self.last_heard > STALL:
            self.stall_end = now
        self.last_heard = now

    def in_stall(self, issued: float) -> bool:
        """Whether a command issued then was made while the link was stalled (before it came back)."""
        return issued < self.stall_end - STALL_SLACK

    def sample(self, t_ms: float, now: float) -> float:
        """Take the stamp ``t_ms`` of an op arriving at ``now`` (loop time, s); return when it was
        issued on the loop's clock (its arrival over the fastest path seen)."""
        t = t_ms / 1000.0
        offset = now - t
        if self.base is None:
            self.base = offset
        else:
            self.base = min(offset, self.base + DRIFT * max(0.0, now - self.at))
        self.at = now
        return t + self.base


class Fence:
    """After a stop, a connection's moving commands wait for its answer to a ping.

    ``raise_()`` at a stop sends a websocket ping carrying a new token; until the pong with that
    token comes back (``pong``), ``up`` is true and the safety rules drop the connection's moving
    unstamped commands: what the client sent before it saw the ping. An older pong (a ping of an
    earlier stop, the transport's keep-alive) does not lower it. A client that never answers
    pings cannot move the robot again on that connection. ``ping`` is None for a transport
    without pings: no fence."""

    __slots__ = ('ping', 'token', 'raised')

    def __init__(self, ping=None) -> None:
        self.ping = ping           # ping(data: bytes): a websocket ping on the connection
        self.token: bytes | None = None
        self.raised = 0

    @property
    def up(self) -> bool:
        return self.token is not None

    def raise_(self) -> None:
        if self.ping is None:
            return
        self.raised += 1
        self.token = b'rosgate-stop-%d' % self.raised
        try:
            self.ping(self.token)
        except Exception:      # the connection is closing: nothing more comes from it anyway
            pass

    def pong(self, data: bytes) -> None:
        if self.token is not None and data == self.token:
            self.token = None
