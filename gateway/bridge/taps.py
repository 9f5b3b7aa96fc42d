"""The doors the bridge opens to the parts that are not clients (``media``, ``twin``), built from the
Gateway here so that none of them holds it.

``Taps``: the topics' shared fan-outs, found or made (``media.ports.Taps``, ``twin.ports.Taps``): a
recording, a camera stream, the history and a robot's description read a topic as one more
subscriber of the backend subscription every client shares. ``Senders``: the one publish door for
someone who is not a client (``media.ports.Senders``: a playback publishes for its starter, the
rules applying as to that person's own ops).
"""

from __future__ import annotations

from .gateway import Gateway, Sender


class Taps:
    """``media.ports.Taps`` and ``twin.ports.Taps`` of one Gateway."""

    def __init__(self, gateway: Gateway):
        self.topic_type = gateway.topic_type
        self.fanout = gateway.fanout
        self.drop_fanout = gateway.drop_fanout


class Senders:
    """``media.ports.Senders`` of one Gateway: its senders, its publishers and its door."""

    def __init__(self, gateway: Gateway):
        self.open_sender, self.close_sender = gateway.open_sender, gateway.close_sender
        self.open_publisher, self.publish = gateway.open_publisher, gateway.publish

    @staticmethod
    def probe(name: str, role: str | None, person: str | None = None) -> Sender:
        """A sender never opened: what the rules are asked about before a playback publishes."""
        return Sender(name, role, person=person)
