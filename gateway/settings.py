"""Gateway settings: one frozen object built by the CLI (names follow rosbridge_server's
parameters), and where things are on disk.

An installed wheel (or a colcon install) carries the IDE pages and the example programs as
package data in ``gateway/_assets/`` (copied there by setup.py at build time); a checkout, and an
editable install of it, serves the checkout's own ``ide/`` and ``examples/``, so a developer's
edits show on reload. What the gateway stores (programs, runs, recordings) goes under the user's
XDG data directory.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
PACKAGED = PACKAGE / '_assets'        # in a wheel
CHECKOUT = PACKAGE.parent             # the repository root, beside gateway/


def _locate(name: str) -> Path:
    for base in (PACKAGED, CHECKOUT):
        if (base / name).is_dir():
            return base / name
    return PACKAGED / name


def ide_dir() -> Path:
    """The directory served at ``/`` (index.html, teleop.html, js/, css/, vendor/, ...)."""
    return _locate('ide')


def examples_dir() -> Path:
    """The example programs served at ``/examples/``."""
    return _locate('examples')


def data_dir(name: str) -> Path:
    """``$XDG_DATA_HOME/rosgate/NAME`` (``~/.local/share/rosgate/NAME`` when unset)."""
    base = os.environ.get('XDG_DATA_HOME') or os.path.join(os.path.expanduser('~'), '.local', 'share')
    return Path(base) / 'rosgate' / name


@dataclass(frozen=True)
class Settings:
    port: int = 9090
    address: str = ''
    url_path: str = '/'
    certfile: str | None = None
    keyfile: str | None = None
    max_message_size: int = 10 * 2**20         # incoming frame limit (bytes)
    fragment_timeout: float = 600.0
    unregister_timeout: float = 10.0           # grace before an unadvertised publisher is destroyed
    use_compression: bool = False              # permessage-deflate
    default_call_service_timeout: float = 5.0
    websocket_ping_interval: float = 20.0      # below the idle timeouts of common proxies (nginx 60 s)
    websocket_ping_timeout: float = 30.0
    send_buffer_limit: int = 16 * 2**20        # per-client queued bytes before topic messages drop
    body_timeout: float = 30.0                 # s to send a request body before the connection closes
    idle_connection_timeout: float = 60.0      # s an HTTP connection may wait for its next request's headers
    auth_timeout: float = 30.0                 # s a websocket has to authenticate under --auth
    default_queue_length: int = 100            # per-subscription queued messages when queue_length is 0
    allowed_hosts: str | None = None         # globs of Host names besides IPs, localhost and this machine's
    allowed_origins: str | None = None       # globs of browser origins besides our own (scheme, host, port)
    topics_glob: str | None = None
    services_glob: str | None = None
    params_glob: str | None = None
    actions_glob: str | None = None
    topics_pub_glob: str | None = None
    topics_sub_glob: str | None = None
    backend: str = 'auto'
    node_name: str = ''                        # empty: rosgate_<host>_<port> (cli.default_node_name)
    ide_dir: Path = field(default_factory=ide_dir)             # package data, or the checkout's ide/
    examples_dir: Path = field(default_factory=examples_dir)
    programs_dir: Path | None = None
    allow_runs: bool = False                   # POST /api/runs executes programs on this machine
    trusted_runs: bool = False                 # runs on the ROS graph themselves, outside the rules
    runs_dir: Path | None = None               # runs' working directories (None: the XDG data dir)
    max_runs: int = 4                          # runs going at once
    max_runs_per_person: int = 2               # of those, one signed-in non-admin's
    recordings_dir: Path | None = None         # where recordings go (None: --record's, else the XDG data dir)
    record: Path | None = None                 # record from start-up into this directory
    record_topics: str | None = None           # globs of the topics --record takes
    db_url: str | None = None                  # the store (None: SQLite in the data directory)
    history: str | None = None                 # globs of the topics kept (None: battery, temperature, odometry; 'none': off)
    history_max_mb: float = 1024.0             # the history's cap in the store
    history_full_hours: float = 24.0           # full rate (1 Hz) this long, per-minute rows before
    opcua: int | None = None                   # OPC UA server on this port (0: any free one)
    urdf: Path | None = None                   # the twin's robot description when not from the graph
    mesh_path: tuple = ()                      # folders of description packages served at /package/
    extra: dict = field(default_factory=dict)  # options of optional parts (robots, security)
