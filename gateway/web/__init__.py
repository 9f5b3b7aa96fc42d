"""The HTTP side: thin routes over the parts the server started (``gateway.server``).

Rooms: the route table (``app``: ``make_app``, and ``socket_app``, the websocket alone for the runs'
unix socket); the rosbridge websocket (``socket``); the pages, the Host/body checks in front of every
request (``pages``); the JSON API base (``api``: ``Handler``, the one place errors and domain refusals
become answers; who is asking; query numbers); and the apps: the program library (``programs``),
robot-side runs (``runs``: HTTP only, the runs themselves are ``gateway.runs``), recordings and their
playback (``recordings``, over ``media.recordings``), the robots' history (``history``, over
``twin.history`` and ``twin.queries``), the robot's description, packages and gauges
(``description``, ``packages``, ``gauges``, over ``twin``), bookings and the walk-ins' queue
(``bookings``), web_video_server's camera URLs (``video``, over ``media.video``), the teacher's class
view (``classview``), signing in
(``login``; ``lti``: launches from an LMS; ``cookies``: the cookie attributes browsers need in and
out of an LMS's iframe); what the process logs, scrubbed of tokens and forged lines (``logs``).

Each route is handed what its handlers use (the policy, the store, a setting, a part, the backend's
topics typed by a small ``Protocol`` beside the handler), never the whole Gateway: only ``app`` (the
websocket route, /health) and ``socket`` hold it. The ``Application`` holds the policy, which
``api.authorized`` asks (``api.Access``). HTTP only: no store, no hook, no domain class here
(``tests/gateway/test_layers.py::test_web_is_http_only``); the domain is in its room.

May import: ``bridge``, ``media``, ``twin``, ``runs``, ``exercises``, ``rules``, ``store``, ``backends``
(types), ``protocol``, ``settings``.
"""
