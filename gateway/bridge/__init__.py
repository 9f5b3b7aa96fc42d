"""The rosbridge side: per-client sessions (``session``), one small handler per op family
(``capabilities``: topics, services, actions), ``rosapi``, the shared fan-out (``fanout``: one backend
subscription per topic, each message encoded once per encoding, ``encode``; images and maps made to
measure, ``media.images``; marker arrays merged, ``markers``), the bounded per-client outbox (``outbox``), and the
gateway that holds them with the one publish door (``gateway.Gateway.publish``) and the rules in
force (``Gateway.install``).

Data flows frame -> op (``protocol``) -> rules (``rules``) -> backend -> fan-out -> outbox.
May import: ``protocol``, ``media`` (images), ``rules``, ``auth``, ``store``, ``backends``, ``settings``; never ``web``.
"""
