"""The ``rosgate`` command. Flags mirror rosbridge_server's parameters (``--port`` or ``port:=9090``)."""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import logging
import os
import re
import socket
import sys
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import tornado.netutil

from . import rules
from .backends.rclpy import RclpyBackend
from .backends.sim import SimBackend, robots
from .server import serve
from .settings import Refused, Settings, flat, from_flat
from .web import logs
from .web.fastio import loop_factory
from .twin.description import check_urdf
from .twin.gauges import read_limits
from .twin.history import history_globs

log = logging.getLogger('rosgate')


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='rosgate',
        description='A rosbridge v2 gateway with an embedded ROS graph, simulated robots and a block IDE. '
                    'Flags also accept the ROS form name:=value.')
    d = Settings()
    g = p.add_argument_group('rosbridge_server parameters')
    g.add_argument('--port', type=int, help='port (0 picks a free one) [%(default)s]')
    g.add_argument('--address', help='address to listen on (empty: all)')
    g.add_argument('--url-path', help='websocket path [%(default)s]')
    g.add_argument('--certfile', help='TLS certificate (with --keyfile: wss and https)')
    g.add_argument('--keyfile', help='TLS private key')
    g.add_argument('--max-message-size', type=int,
                   help='largest incoming frame in bytes [%(default)s]')
    g.add_argument('--fragment-timeout', type=float, help='[%(default)s] s')
    g.add_argument('--unregister-timeout', type=float,
                   help='grace before an unadvertised publisher is destroyed [%(default)s] s')
    g.add_argument('--use-compression', action=argparse.BooleanOptionalAction,
                   help='permessage-deflate')
    for kind in ('topics', 'services', 'params', 'actions', 'topics-pub', 'topics-sub'):
        g.add_argument(f'--{kind}-glob', help=f"allowed {kind.replace('-', ' ')} names, e.g. \"['/turtle1/*']\"")
    g.add_argument('--default-call-service-timeout', type=float,
                   help='[%(default)s] s')
    g.add_argument('--websocket-ping-interval', type=float, metavar='S',
                   help='ping every websocket this often, so a proxy does not cut a quiet one (nginx: 60 s); '
                        '0 for never [%(default)s]')
    g.add_argument('--websocket-ping-timeout', type=float, metavar='S',
                   help='close a websocket that has not answered a ping this long, at most the ping interval '
                        '(a longer one is cut to it, with a warning at start) [%(default)s, as rosbridge_server]')
    g.add_argument('--send-buffer-limit', type=int,
                   help='bytes queued per client before its topic messages are dropped [%(default)s]')
    g.add_argument('--body-timeout', type=float, metavar='S',
                   help='seconds a client has to send a request body; a slower one is cut off [%(default)s]')
    g.add_argument('--idle-connection-timeout', type=float, metavar='S',
                   help='seconds an HTTP connection may sit without sending a request\'s headers [%(default)s]')
    g.add_argument('--auth-timeout', type=float, metavar='S',
                   help='with --auth, seconds a websocket has to authenticate before it is closed [%(default)s]')
    g.add_argument('--allowed-hosts', help='Host names the gateway answers to besides IP addresses, localhost and '
                                            'this machine\'s names (globs, e.g. "[\'robot.example.org\']"); '
                                            'others get 421 (DNS rebinding)')
    g.add_argument('--allowed-origins', help='browser origins allowed besides the gateway\'s own (same scheme, host '
                                              'and port; localhost for 127.0.0.1), globs, e.g. '
                                              '"[\'http://localhost:5173\']" ("*" for any)')
    g.add_argument('--fast-io', action=argparse.BooleanOptionalAction,
                   help='compiled I/O where installed: picows for websockets without TLS or deflate, uvloop '
                        'under tornado (--no-fast-io: tornado and asyncio alone) [%(default)s]')
    b = p.add_argument_group('backend')
    b.add_argument('--backend', dest='backend.kind', choices=('auto', 'sim', 'rclpy'),
                   help='auto: rclpy when it imports, else the embedded sim [%(default)s]')
    b.add_argument('--node-name',
                   help='the gateway node name [rosgate_<host>_<port>: gateways on one graph differ]')
    b.add_argument('--interfaces', dest='backend.interfaces', type=Path, action='append', metavar='DIR',
                   help='rclpy: <pkg>/srv/<Name>.srv (and action, msg) texts of services and actions '
                        'this machine lacks; built on first use (repeatable)')
    b.add_argument('--interface-cache', dest='backend.interface_cache', type=Path, metavar='DIR',
                   help='rclpy: where interfaces built on first use are kept [~/.cache/rosgate/interfaces]')
    b.add_argument('--talker', dest='sim.talker', action='store_true', help='sim: publish /chatter once a second')
    b.add_argument('--fibonacci-interval', dest='sim.fibonacci_interval', type=float,
                   help='sim: seconds between /fibonacci steps [%(default)s]')
    b.add_argument('--programs-dir', dest='storage.programs_dir', type=Path,
                   help='where the IDE program library is stored [%(default)s]')
    b.add_argument('--blocks-dir', dest='storage.blocks_dir', type=Path, metavar='DIR',
                   help='a folder of block sets (JSON files, each listed in the IDE\'s toolbox for its robot); '
                        'blocks an admin publishes from the IDE are kept there too (shared.json)')
    b.add_argument('--exercises-dir', dest='lab.exercises_dir', type=Path, metavar='DIR',
                   help='a folder of exercises (ID.json: start program, station kind, time limit, goal); '
                        'those an admin makes with POST /api/exercises are kept there too [%(default)s]')
    r = p.add_argument_group('robot-side runs and recordings')
    r.add_argument('--allow-runs', dest='runs.allow_runs', action='store_true',
                   help='let operators run programs as processes on this machine (POST /api/runs): '
                        'this executes code sent over the network')
    r.add_argument('--trusted-runs', dest='runs.trusted_runs', action='store_true',
                   help='with --allow-runs: runs join the ROS graph themselves (the gateway\'s ROS and DDS '
                        'variables, no network of their own), for programs that are real ROS 2 nodes at full '
                        'speed. What they publish that way is OUTSIDE every rule of the gateway: no lease, '
                        'glob, clamp, stop or slot end applies to it. For a robot whose operators are trusted')
    r.add_argument('--runs-dir', dest='runs.runs_dir', type=Path, help='where runs get their working directories '
                                                 '[$XDG_DATA_HOME/rosgate/runs]')
    r.add_argument('--max-runs', dest='runs.max_runs', type=_at_least_one, metavar='N',
                   help='runs going at once [%(default)s]')
    r.add_argument('--max-runs-per-person', dest='runs.max_runs_per_person', type=_at_least_one, metavar='N',
                   help='runs going at once for one signed-in person, admins excepted (with --auth) [%(default)s]')
    r.add_argument('--run-output-cap', dest='runs.run_output_cap', type=_size, metavar='BYTES',
                   help='output of a run kept in the store (1M, 512K ...); past it a line says where it was cut '
                        '[%(default)s]')
    r.add_argument('--runs-keep-days', dest='runs.runs_keep_days', type=float, metavar='DAYS',
                   help='kept runs (source, output, recording) older than this are deleted [%(default)s]')
    r.add_argument('--runs-keep-count', dest='runs.runs_keep_count', type=_at_least_one, metavar='N',
                   help='each person\'s newest N runs are kept, older ones deleted [%(default)s]')
    r.add_argument('--runs-keep-bytes', dest='runs.runs_keep_bytes', type=_size, metavar='BYTES',
                   help='the kept runs in all (2G, 500M ...): the oldest go past it, and a run that could not '
                        'fit is refused (507) [%(default)s]')
    r.add_argument('--runs-keep-share', dest='runs.runs_keep_share', type=_share, metavar='F',
                   help='the most of --runs-keep-bytes one person\'s kept runs may take (0.25: a quarter); past it '
                        'their own oldest go, never another\'s [%(default)s]')
    r.add_argument('--recordings-dir', dest='storage.recordings_dir', type=Path, metavar='DIR',
                   help='where recordings made from the pages and /api/recordings go '
                        '[--record\'s DIR, else $XDG_DATA_HOME/rosgate/recordings]')
    r.add_argument('--record', dest='storage.record', type=Path, metavar='DIR',
                   help='record from start-up into DIR (also where /api/recordings keeps its files, '
                        'unless --recordings-dir says otherwise)')
    r.add_argument('--record-topics', dest='storage.record_topics', metavar='GLOBS', help='topics --record takes, e.g. "[\'/turtle1/*\']" [all]')
    r.add_argument('--db', '--history-db', dest='storage.db_url', metavar='URL',
                   help='where sign-in sessions, bookings and history are kept: an SQLAlchemy URL, e.g. '
                        'postgresql+psycopg://rosgate@dbhost/rosgate [sqlite:///$XDG_DATA_HOME/rosgate/rosgate.db]')
    h = p.add_argument_group('history and the twin')
    h.add_argument('--history', dest='twin.history', metavar='GLOBS',
                   help='topics whose numeric fields the gateway keeps, e.g. "[\'/s*/battery_state\', \'/turtle1/pose\']"; '
                        '"none" keeps nothing [every topic of type BatteryState, Temperature, Odometry or turtlesim Pose]')
    h.add_argument('--history-max-mb', dest='twin.history_max_mb', type=float, metavar='MB',
                   help='past this size in the store, the oldest history goes [%(default)s]')
    h.add_argument('--history-full-hours', dest='twin.history_full_hours', type=float, metavar='H',
                   help='history kept at full rate (1 Hz) this long, then as per-minute min/mean/max [%(default)s]')
    h.add_argument('--opcua', dest='twin.opcua', type=int, metavar='PORT',
                   help='serve the robots\' history fields and pose over OPC UA on this port (0: any free one)')
    h.add_argument('--urdf', dest='twin.urdf', type=Path, metavar='FILE',
                   help='the robot description the 3D twin draws (served at /urdf), in place of the '
                        'robot_description topic: URDF or xacro ($(find PKG) through the package roots and '
                        '--mesh-path)')
    h.add_argument('--mesh-path', dest='twin.mesh_path', type=Path, action='append', metavar='DIR',
                   help='a folder of description packages (DIR/PKG/meshes/...) whose files the twin loads '
                        'as package://PKG/..., besides AMENT_PREFIX_PATH\'s share folders (repeatable)')
    h.add_argument('--gauges', dest='twin.gauges', type=Path, metavar='FILE',
                   help='the dashboard\'s gauge limits, once per robot: a JSON or TOML table of topic names or '
                        'globs to {min, max, warn, danger, low} (served at /api/gauges)')
    b.add_argument('--log-level', choices=('debug', 'info', 'warning', 'error'))
    robots.add_arguments(p)
    rules.add_arguments(p)
    p.set_defaults(**flat(d))   # every default is the field's (gateway.settings)
    for action in p._actions:    # --max-runs N, not RUNS.MAX_RUNS: the dest holds the group
        if '.' in action.dest and action.metavar is None and action.nargs != 0:
            action.metavar = action.option_strings[0][2:].upper().replace('-', '_')
    return p


def _at_least_one(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'at least 1, not {value}')
    return value


def _share(text: str) -> float:
    value = float(text)
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f'a share above 0 and at most 1 (0.25: a quarter), not {text!r}')
    return value


def _size(text: str) -> int:
    """Bytes, with K, M or G (powers of 1024) after the number if wished."""
    units = {'K': 2**10, 'M': 2**20, 'G': 2**30}
    text = text.strip().upper().removesuffix('B').removesuffix('I')
    try:
        value = int(float(text[:-1]) * units[text[-1]]) if text[-1:] in units else int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'a number of bytes like 1048576, 512K, 1M or 2G, not {text!r}') from None
    if value < 1:
        raise argparse.ArgumentTypeError(f'at least 1 byte, not {value}')
    return value


def ros_style(argv: list[str], parser: argparse.ArgumentParser | None = None) -> list[str]:
    """Turn ROS launch style ``port:=9090`` into ``--port 9090``; ``--ros-args`` and after are kept aside.

    With the parser, switches take ROS booleans: ``use_compression:=true`` is ``--use-compression``,
    ``use_compression:=false`` is ``--no-use-compression`` (or nothing for a switch that is off by default).
    """
    switches = {s: a for s, a in (parser._option_string_actions.items() if parser else ()) if a.nargs == 0}
    out = []
    for arg in argv:
        if ':=' in arg and not arg.startswith('-'):
            key, value = arg.split(':=', 1)
            flag = f"--{key.replace('_', '-')}"
            if flag in switches:
                off = '--no-' + flag[2:]
                on = value.strip().lower() in ('true', '1', 'yes', 'on')
                out += [flag] if on else [off] if off in switches else []
            else:
                out += [flag, value]
        else:
            out.append(arg)
    return out


def settings_from(args: argparse.Namespace) -> Settings:
    """Every flag's value in its field (each dest names one: ``port``, ``security.auth_backoff``)."""
    return from_flat(vars(args))


class Start(NamedTuple):
    """What the start-up check read: the rules' files and the simulated robots."""
    files: rules.Files
    robots: tuple


def check(settings: Settings) -> Start:
    """The one validation of the settings, at start-up, before anything starts: a Refused names
    the flags (``main`` prints it and exits 2). Flags whose values argparse cannot parse were
    refused already, the same way (a usage line, exit 2)."""
    try:
        files = rules.load(settings)
    except rules.ConfigError as e:
        raise Refused(e.flags, e.why) from None
    try:
        specs = robots.specs_from(settings.sim)
    except ValueError as e:
        flag, _, why = str(e).partition(': ')    # 'FLAG: why' (robots.specs_from)
        raise Refused(flag, why) from None
    runs = settings.runs
    if runs.trusted_runs and not runs.allow_runs:
        raise Refused('--trusted-runs', 'it is a kind of run: give --allow-runs too')
    twin = settings.twin
    if twin.gauges is not None:
        try:
            read_limits(twin.gauges)
        except (OSError, ValueError) as e:
            raise Refused('--gauges', str(e)) from None
    interval, timeout = settings.websocket_ping_interval, settings.websocket_ping_timeout
    if interval and timeout and timeout > interval:   # tornado's ping waits for its pong one interval at most
        logging.getLogger('rosgate').warning('--websocket-ping-timeout %g s is cut to --websocket-ping-interval %g s: '
                                             'a ping is answered before the next one, or the socket closes',
                                             timeout, interval)
    try:
        check_urdf(twin.urdf, twin.mesh_path)   # xacro is expanded now: a file it cannot expand stops here
    except ValueError as e:
        raise Refused('--urdf', str(e)) from None
    if twin.opcua is not None:
        if history_globs(twin.history) is False:
            raise Refused('--opcua, --history', '--opcua serves the history, and --history none keeps none')
        if importlib.util.find_spec('asyncua') is None:
            raise Refused('--opcua', 'it needs asyncua: pip install "rosgate[opcua]"')
    return Start(files, specs)


def refuse(refused: Refused) -> int:
    """The one way the gateway refuses to start: a line naming the flags on stderr, exit status 2."""
    print(f'rosgate: {refused}', file=sys.stderr)
    return 2


def default_node_name(port: int, host: str | None = None) -> str:
    """``rosgate_<host>_<port>``: the same name at every start of a gateway, and different names
    for gateways on one graph (another port or another machine). A valid ROS node name: letters,
    digits and single underscores."""
    host = (host if host is not None else socket.gethostname()).split('.')[0]
    name = re.sub(r'[^A-Za-z0-9]+', '_', f'rosgate_{host}_{port}', flags=re.ASCII)
    return re.sub(r'_+', '_', name).strip('_')


def make_backend(settings: Settings, robot_specs: tuple, ros_args: list[str], node_name: str):
    choice = settings.backend.kind
    if choice == 'auto':
        try:
            import rclpy  # noqa: F401
            choice = 'rclpy'
        except ImportError:
            choice = 'sim'
    if choice == 'rclpy':
        return RclpyBackend(node_name=node_name, ros_args=ros_args, interfaces=settings.backend.interfaces,
                            interface_cache=settings.backend.interface_cache)
    return SimBackend(node_name=node_name, talker=settings.sim.talker,
                      fibonacci_interval=settings.sim.fibonacci_interval, robots=robot_specs)


def announce(line: str) -> None:
    """A start-up line on stdout. A launcher that read the first line and closed its end (a test
    runner, a supervisor) is no reason to stop serving: later lines then go nowhere."""
    try:
        print(line, flush=True)
    except BrokenPipeError:
        sys.stdout = open(os.devnull, 'w')


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args: list[str] = []
    if '--ros-args' in argv:
        i = argv.index('--ros-args')
        argv, ros_args = argv[:i], argv[i:]
    parser = build_parser()
    args = parser.parse_args(ros_style(argv, parser))
    logging.basicConfig(level=args.log_level.upper(), format='%(asctime)s %(levelname)s %(name)s: %(message)s',
                        stream=sys.stderr)
    logs.install()   # no tokens in the log, no line forged by a name with a newline
    logging.getLogger('tornado.access').setLevel(logging.WARNING)
    settings = settings_from(args)
    try:
        start = check(settings)
    except Refused as e:
        return refuse(e)
    # bound before the backend starts: the default node name holds the port (also when it is 0)
    sockets = tornado.netutil.bind_sockets(settings.port, settings.address or None)
    node_name = settings.node_name or default_node_name(sockets[0].getsockname()[1])
    settings = replace(settings, node_name=node_name)
    backend = make_backend(settings, start.robots, ros_args, node_name)
    try:
        with asyncio.Runner(loop_factory=loop_factory(settings.fast_io)) as runner:
            runner.run(serve(settings, start.files, backend, sockets, announce=announce))
    except Refused as e:     # a part that cannot start here (no bwrap for --allow-runs)
        return refuse(e)
    except KeyboardInterrupt:
        pass
    return 0
