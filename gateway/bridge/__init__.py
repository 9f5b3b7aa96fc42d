"""The rosbridge side: per-client sessions, one small handler per op family (``capabilities``),
rosapi, the shared fan-out (one backend subscription per topic, each message encoded once per
encoding), the bounded per-client outbox, and the gateway that holds them with the one publish
door (``gateway.Gateway.publish``).

Data flows frame -> op (``protocol``) -> rules (``rules``) -> backend -> fan-out -> outbox.
May import: ``protocol``, ``rules``, ``backends``, ``settings``; never ``web``.
"""
