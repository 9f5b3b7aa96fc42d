"""Gateway settings: one frozen object built by the CLI, and where things are on disk.

Every flag is one typed field with its one default, here: the rosbridge_server parameters at the
top (their names follow rosbridge's), the rest grouped by concern (``backend``, ``sim``,
``security``, ``safety``, ``stations``, ``lab``, ``runs``, ``storage``, ``twin``). The CLI
takes its defaults from these fields (each flag's ``dest`` is ``group.field``), and
``cli.check`` validates the whole object once at start-up (a refusal names the flags and exits 2).

An installed wheel (or a colcon install) carries the IDE pages and the example programs as
package data in ``gateway/_assets/`` (copied there by setup.py at build time); a checkout, and an
editable install of it, serves the checkout's own ``ide/`` and ``examples/``, so a developer's
edits show on reload. What the gateway stores (programs, runs, recordings) goes under the user's
XDG data directory.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
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


class Refused(Exception):
    """The gateway will not start as asked: ``flags`` names the flags, the message says why. The
    CLI's one way to refuse (a line on stderr, exit status 2)."""

    def __init__(self, flags: str, message: str):
        super().__init__(f'{flags}: {message}')
        self.flags, self.message = flags, message


@dataclass(frozen=True)
class BackendSettings:
    kind: str = 'auto'                         # auto: rclpy when it imports, else the embedded sim
    interfaces: tuple[Path, ...] = ()          # rclpy: .srv/.action/.msg texts built on first use
    interface_cache: Path | None = None        # rclpy: where they are kept (None: ~/.cache/rosgate/interfaces)


@dataclass(frozen=True)
class SimSettings:
    robot: tuple[str, ...] | None = None       # robots per station (None: turtlesim; 'none' for none)
    world: str = 'arena'                       # the rover's world: arena, maze or a .json file
    twist_stamped: bool = False                # the rover's cmd_vel is a TwistStamped
    fleet: int = 0                             # N stations /s01../sNN
    sim_speed: float = 1.0                     # simulation speed factor (tests)
    talker: bool = False                       # publish /chatter once a second
    fibonacci_interval: float = 1.0            # s between /fibonacci steps


@dataclass(frozen=True)
class SecuritySettings:
    auth: Path | None = None                   # TOML file mapping tokens to roles (None: no tokens)
    auth_backoff: float = 0.5                  # s after 3 failed attempts from an address, doubling
    session_hours: float = 12.0                # a sign-in lasts this long
    lti: Path | None = None                    # PyLTI1p3 tool configuration JSON (LMS launches)
    trusted_proxies: str | None = None         # addresses/networks whose X-Forwarded-* are believed
    max_subscriptions: int = 1000              # per client
    max_publishers: int = 1000                 # per client
    max_pending_calls: int = 256               # service calls and action goals in flight per client
    max_op_rate: float = 0.0                   # ops per second per client; 0: unlimited


@dataclass(frozen=True)
class SafetySettings:
    stop_on_disconnect: bool = True            # zero a command when its driver goes away
    stop_types: tuple[str, ...] = ('geometry_msgs/msg/Twist', 'geometry_msgs/msg/TwistStamped')
    cmd_timeout: float = 1.0                   # s; zero a command stream silent this long (0: never)
    cmd_max_age: float = 0.3                   # s a stamped moving command may wait beyond its link's fastest trip
    require_cmd_stamp: bool = False            # refuse moving commands without a stamp
    max_linear: float | None = None            # m/s clamp
    max_angular: float | None = None           # rad/s clamp
    velocity_limits: Path | None = None        # per-topic clamps ([[limits]] TOML)
    exclusive_control: bool = False            # one driver per robot (the lease)
    control_glob: str | None = None            # more names under the lease, each glob its own


@dataclass(frozen=True)
class StationSettings:
    claim_idle: float = 3600.0                 # s a person's station stays theirs with none of their pages connected
    claim_grace: float = 60.0                  # s a script's station stays its own after it leaves


@dataclass(frozen=True)
class LabSettings:
    booking: bool = False                      # stations booked ahead in slots
    slot_minutes: float = 60.0                 # the longest slot
    booking_per_day: int = 8                   # slots per person per day, admins excepted (0: no limit)
    booking_per_week: int = 30                 # per ISO week (0: no limit)
    booking_ahead: float = 14.0                # days ahead a slot may begin (0: no limit)
    station_reset: str | None = None           # service called in the station's namespace at a slot's end
    exercises_dir: Path | None = field(default_factory=lambda: data_dir('exercises'))   # exercises (JSON files)


@dataclass(frozen=True)
class RunSettings:
    allow_runs: bool = False                   # POST /api/runs executes programs on this machine
    trusted_runs: bool = False                 # runs on the ROS graph themselves, outside the rules
    runs_dir: Path | None = None               # runs' working directories (None: the XDG data dir)
    max_runs: int = 4                          # runs going at once
    max_runs_per_person: int = 2               # of those, one signed-in non-admin's
    run_output_cap: int = 2**20                # bytes of a run's output kept in the store
    runs_keep_days: float = 180.0              # kept runs older than this are deleted
    runs_keep_count: int = 500                 # each person's newest kept runs
    runs_keep_bytes: int = 2 * 2**30           # the kept runs' output, sources and recordings in all
    runs_keep_share: float = 0.25              # of runs_keep_bytes, the most one person's kept runs take


@dataclass(frozen=True)
class StorageSettings:
    programs_dir: Path | None = field(default_factory=lambda: data_dir('programs'))   # the IDE's library
    blocks_dir: Path | None = None             # robots' block sets and the class's published blocks (JSON)
    recordings_dir: Path | None = None         # where recordings go (None: --record's, else the XDG data dir)
    record: Path | None = None                 # record from start-up into this directory
    record_topics: str | None = None           # globs of the topics --record takes
    db_url: str | None = None                  # the store (None: SQLite in the data directory)


@dataclass(frozen=True)
class TwinSettings:
    history: str | None = None                 # globs of the topics kept (None: battery, temperature, odometry; 'none': off)
    history_max_mb: float = 1024.0             # the history's cap in the store
    history_full_hours: float = 24.0           # full rate (1 Hz) this long, per-minute rows before
    opcua: int | None = None                   # OPC UA server on this port (0: any free one)
    urdf: Path | None = None                   # the twin's robot description when not from the graph
    mesh_path: tuple = ()                      # folders of description packages served at /package/
    gauges: Path | None = None                 # the dashboard's gauge limits per robot (JSON or TOML), at /api/gauges


GROUPS = {'backend': BackendSettings, 'sim': SimSettings, 'security': SecuritySettings, 'safety': SafetySettings,
          'stations': StationSettings, 'lab': LabSettings, 'runs': RunSettings, 'storage': StorageSettings,
          'twin': TwinSettings}


@dataclass(frozen=True)
class Settings:
    """The rosbridge_server parameters, then one field per group of the others."""
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
    websocket_ping_interval: float = 30.0      # below the idle timeouts of common proxies (nginx 60 s)
    websocket_ping_timeout: float = 30.0       # rosbridge_server's; tornado waits one interval at most (cli.check)
    send_buffer_limit: int = 16 * 2**20        # per-client queued bytes before topic messages drop
    fast_io: bool = True                       # picows for plain websockets and uvloop, where installed
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
    node_name: str = ''                        # empty: rosgate_<host>_<port> (cli.default_node_name)
    log_level: str = 'info'
    ide_dir: Path = field(default_factory=ide_dir)             # package data, or the checkout's ide/
    examples_dir: Path = field(default_factory=examples_dir)
    backend: BackendSettings = field(default_factory=BackendSettings)
    sim: SimSettings = field(default_factory=SimSettings)
    security: SecuritySettings = field(default_factory=SecuritySettings)
    safety: SafetySettings = field(default_factory=SafetySettings)
    stations: StationSettings = field(default_factory=StationSettings)
    lab: LabSettings = field(default_factory=LabSettings)
    runs: RunSettings = field(default_factory=RunSettings)
    storage: StorageSettings = field(default_factory=StorageSettings)
    twin: TwinSettings = field(default_factory=TwinSettings)


def flat(settings: Settings) -> dict:
    """{'port': 9090, ..., 'security.auth_backoff': 0.5, ...}: the CLI's dests and their defaults
    (tuples as lists, which argparse's append extends)."""
    out = {}
    for f in fields(settings):
        value = getattr(settings, f.name)
        if f.name in GROUPS:
            out.update({f'{f.name}.{k}': v for k, v in flat(value).items()})
        else:
            out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


def from_flat(values: dict) -> Settings:
    """The inverse of ``flat``; a key that names no field is a KeyError (a flag without a home)."""
    top, groups = {}, {name: {} for name in GROUPS}
    for key, value in values.items():
        value = tuple(value) if isinstance(value, list) else value
        group, _, name = key.rpartition('.')
        if group:
            if name not in {f.name for f in fields(GROUPS[group])}:
                raise KeyError(key)
            groups[group][name] = value
        elif key in {f.name for f in fields(Settings)} and key not in GROUPS:
            top[key] = value
        else:
            raise KeyError(key)
    return Settings(**top, **{name: GROUPS[name](**kw) for name, kw in groups.items()})
