"""rosgate: a rosbridge v2 gateway with an embedded ROS graph, simulated robots and a block IDE.

By role, imports pointing one way (web -> bridge, runs -> rules -> store, backends -> protocol):

- ``web/``      the tornado app: thin routes, websocket, pages, program library, recordings, history, class view
- ``bridge/``   the rosbridge side: sessions, op handlers, rosapi, fan-out, outbox, the publish door
- ``runs/``     robot-side runs: the supervisor, the bwrap sandbox, cgroups, the launcher
- ``rules/``    who may do what and keeping robots safe: the one access rule, roles, tokens, caps, lease,
                clamps, stops, stations and bookings, the typed hooks; composed in one place
- ``store/``    what is kept across restarts (bookings, history): one database, SQLite or PostgreSQL
- ``backends/`` the ROS side: ``sim/`` (embedded graph and robots) and ``rclpy/`` (a real ROS 2 graph)
- ``cli``       the flags, the one start-up check (a refusal names the flags, exit 2)
- ``server``    the server's start: the gateway, its parts in order, the HTTP server
- ``settings``  the frozen settings, one typed field per flag grouped by concern (and where things are on disk)
"""
