"""Gateway settings: one frozen object built by the CLI (names follow rosbridge_server's parameters)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from . import assets


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
    websocket_ping_interval: float = 0.0
    websocket_ping_timeout: float = 30.0
    send_buffer_limit: int = 16 * 2**20        # per-client queued bytes before topic messages drop
    default_queue_length: int = 100            # per-subscription queued messages when queue_length is 0
    allowed_hosts: str | None = None         # globs of Host names besides IPs, localhost and this machine's
    allowed_origins: str | None = None       # globs of browser origins besides our own and localhost
    topics_glob: str | None = None
    services_glob: str | None = None
    params_glob: str | None = None
    actions_glob: str | None = None
    topics_pub_glob: str | None = None
    topics_sub_glob: str | None = None
    backend: str = 'auto'
    node_name: str = 'rosgate'
    ide_dir: Path = field(default_factory=assets.ide_dir)             # package data, or the checkout's ide/
    examples_dir: Path = field(default_factory=assets.examples_dir)
    programs_dir: Path | None = None
    allow_runs: bool = False                   # POST /api/runs executes programs on this machine
    runs_dir: Path | None = None               # runs' working directories (None: the XDG data dir)
    max_runs: int = 4                          # runs going at once
    max_runs_per_person: int = 2               # of those, one signed-in non-admin's
    record: Path | None = None                 # record from start-up into this directory
    record_topics: str | None = None           # globs of the topics --record takes
    extra: dict = field(default_factory=dict)  # options of optional parts (robots, security)
