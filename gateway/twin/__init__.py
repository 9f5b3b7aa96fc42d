"""The twin: the robots' past and their description, for the 3D twin page, the dashboards' plots and
the industrial clients of a plant.

Rooms: the history (``history``: the numeric fields of chosen topics kept in the store, at full rate
then per minute, whether or not a page is open; ``queries``: reading it back), the OPC UA server
(``opcua``: the history's latest values as a read-only address space), the robot's description
(``description``: --urdf, the topic or the parameter, xacro expanded in a child process run as a
script, ``xacro_child``), the description packages' files (``packages``: the package roots and the
checks on a path) and the dashboard's gauge limits (``gauges``). The HTTP routes are ``web.history``,
``web.description``, ``web.packages`` and ``web.gauges``.

May import: ``rules``, ``auth``, ``store``, ``backends`` (types) and ``settings``; never ``bridge`` or
``web``. Each part is handed the few doors it uses, typed in ``ports`` (the topics' fan-outs, the
backend's listings, the rules' answer about a name, the store, the fleet's timekeeper), never the
Gateway: the bridge builds the fan-outs' door (``bridge.taps``).
"""
