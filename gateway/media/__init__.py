"""Media: what the gateway makes of topics as pictures and over time, for streams and recordings.

Rooms: images made to measure for a subscriber (``images``: a camera's frame scaled and encoded as
JPEG or PNG; ``grids``: a map shrunk to the size asked for), which the bridge's fan-out renders once
per frame for every client; web_video_server's camera streams (``video``: a source per topic and
size, its viewers, each holding at most one frame); recordings as rosbag2/MCAP (``recordings``:
what is recorded, as whom, with its limits) and their playback through the one publish door
(``playback``). The HTTP routes are ``web.video`` and ``web.recordings``.

May import: ``rules``, ``auth``, ``store``, ``backends`` (types) and ``settings`` (and ``protocol``);
never ``bridge`` or ``web``: the bridge imports ``images`` and ``grids``. Each part is handed the few
doors it uses, typed in ``ports`` (the topics' fan-outs, the publish door for a playback, the
backend's topics and types, the rules' answer about a name), never the Gateway: the bridge builds
them (``bridge.taps``).
"""
