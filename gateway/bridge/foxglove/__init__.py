"""The Foxglove face: Foxglove and Lichtblick connect on the rosbridge port and path, with the
websocket subprotocol ``foxglove.websocket.v1`` or ``foxglove.sdk.v1`` (``protocol.foxglove``).

``session``: a Foxglove client is a ``ClientSession`` like any rosbridge client (the same sign-in,
policy, caps, lease, fresh commands, stop on disconnect and outbox), whose frames are Foxglove's
(``session_class(subprotocol)`` is the one choice, made by the websocket handler); ``topics``:
channels subscribed through the shared fan-out (each message's CDR made once for every Foxglove
subscriber) and clients' channels published through the one door; ``calls``: services,
parameters and the connection graph; ``hub``: the graph as channels and services, shared by every
Foxglove session and kept current while one is connected.

May import what ``bridge`` may; nothing of ``web``.
"""
