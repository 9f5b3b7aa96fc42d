"""rosgate: a rosbridge v2 gateway with an embedded ROS graph, simulated robots and a block IDE.

By role, imports pointing one way (web -> bridge -> rules -> store, backends -> protocol):

- ``web/``      the tornado app: routes, websocket, pages, program library, runs, recordings, class view
- ``bridge/``   the rosbridge side: sessions, op handlers, rosapi, fan-out, outbox, the publish door
- ``rules/``    who may do what and keeping robots safe: globs, roles, tokens, caps, lease, clamps, stops
- ``store/``    what is kept across restarts (bookings, history): one database, SQLite or PostgreSQL
- ``backends/`` the ROS side: ``sim/`` (embedded graph and robots) and ``rclpy/`` (a real ROS 2 graph)
- ``cli``, ``settings``  the process: flags, and the frozen settings (with where things are on disk)
"""
