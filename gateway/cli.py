"""The ``rosgate`` command. Flags mirror rosbridge_server's parameters (``--port`` or ``port:=9090``)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import re
import signal
import socket
import ssl
import sys
from dataclasses import fields, replace
from pathlib import Path

import tornado.httpserver
import tornado.netutil

from . import rules
from .backends.rclpy import RclpyBackend
from .backends.sim import SimBackend, robots
from .bridge import rosapi
from .bridge.gateway import Gateway
from .settings import Settings, data_dir
from .web import logs
from .web.app import make_app
from .web.pages import ide_problem

log = logging.getLogger('rosgate')


def default_programs_dir() -> Path:
    return data_dir('programs')


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='rosgate',
        description='A rosbridge v2 gateway with an embedded ROS graph, simulated robots and a block IDE. '
                    'Flags also accept the ROS form name:=value.')
    d = Settings()
    g = p.add_argument_group('rosbridge_server parameters')
    g.add_argument('--port', type=int, default=d.port, help='port (0 picks a free one) [%(default)s]')
    g.add_argument('--address', default=d.address, help='address to listen on (empty: all)')
    g.add_argument('--url-path', default=d.url_path, help='websocket path [%(default)s]')
    g.add_argument('--certfile', help='TLS certificate (with --keyfile: wss and https)')
    g.add_argument('--keyfile', help='TLS private key')
    g.add_argument('--max-message-size', type=int, default=d.max_message_size,
                   help='largest incoming frame in bytes [%(default)s]')
    g.add_argument('--fragment-timeout', type=float, default=d.fragment_timeout, help='[%(default)s] s')
    g.add_argument('--unregister-timeout', type=float, default=d.unregister_timeout,
                   help='grace before an unadvertised publisher is destroyed [%(default)s] s')
    g.add_argument('--use-compression', action=argparse.BooleanOptionalAction, default=d.use_compression,
                   help='permessage-deflate')
    for kind in ('topics', 'services', 'params', 'actions', 'topics-pub', 'topics-sub'):
        g.add_argument(f'--{kind}-glob', help=f"allowed {kind.replace('-', ' ')} names, e.g. \"['/turtle1/*']\"")
    g.add_argument('--default-call-service-timeout', type=float, default=d.default_call_service_timeout,
                   help='[%(default)s] s')
    g.add_argument('--websocket-ping-interval', type=float, default=d.websocket_ping_interval, metavar='S',
                   help='ping every websocket this often, so a proxy does not cut a quiet one (nginx: 60 s); '
                        '0 for never [%(default)s]')
    g.add_argument('--websocket-ping-timeout', type=float, default=d.websocket_ping_timeout, metavar='S',
                   help='close a websocket that has not answered a ping this long [%(default)s]')
    g.add_argument('--send-buffer-limit', type=int, default=d.send_buffer_limit,
                   help='bytes queued per client before its topic messages are dropped [%(default)s]')
    g.add_argument('--body-timeout', type=float, default=d.body_timeout, metavar='S',
                   help='seconds a client has to send a request body; a slower one is cut off [%(default)s]')
    g.add_argument('--idle-connection-timeout', type=float, default=d.idle_connection_timeout, metavar='S',
                   help='seconds an HTTP connection may sit without sending a request\'s headers [%(default)s]')
    g.add_argument('--auth-timeout', type=float, default=d.auth_timeout, metavar='S',
                   help='with --auth, seconds a websocket has to authenticate before it is closed [%(default)s]')
    g.add_argument('--allowed-hosts', help='Host names the gateway answers to besides IP addresses, localhost and '
                                            'this machine\'s names (globs, e.g. "[\'robot.example.org\']"); '
                                            'others get 421 (DNS rebinding)')
    g.add_argument('--allowed-origins', help='browser origins allowed besides the gateway\'s own (same scheme, host '
                                              'and port; localhost for 127.0.0.1), globs, e.g. '
                                              '"[\'http://localhost:5173\']" ("*" for any)')
    b = p.add_argument_group('backend')
    b.add_argument('--backend', choices=('auto', 'sim', 'rclpy'), default='auto',
                   help='auto: rclpy when it imports, else the embedded sim [%(default)s]')
    b.add_argument('--node-name', default=d.node_name,
                   help='the gateway node name [rosgate_<host>_<port>: gateways on one graph differ]')
    b.add_argument('--interfaces', type=Path, action='append', default=[], metavar='DIR',
                   help='rclpy: <pkg>/srv/<Name>.srv (and action, msg) texts of services and actions '
                        'this machine lacks; built on first use (repeatable)')
    b.add_argument('--interface-cache', type=Path, metavar='DIR',
                   help='rclpy: where interfaces built on first use are kept [~/.cache/rosgate/interfaces]')
    b.add_argument('--talker', action='store_true', help='sim: publish /chatter once a second')
    b.add_argument('--fibonacci-interval', type=float, default=1.0,
                   help='sim: seconds between /fibonacci steps [%(default)s]')
    b.add_argument('--programs-dir', type=Path, default=default_programs_dir(),
                   help='where the IDE program library is stored [%(default)s]')
    r = p.add_argument_group('robot-side runs and recordings')
    r.add_argument('--allow-runs', action='store_true',
                   help='let operators run programs as processes on this machine (POST /api/runs): '
                        'this executes code sent over the network')
    r.add_argument('--trusted-runs', action='store_true',
                   help='with --allow-runs: runs join the ROS graph themselves (the gateway\'s ROS and DDS '
                        'variables, no network of their own), for programs that are real ROS 2 nodes at full '
                        'speed. What they publish that way is OUTSIDE every rule of the gateway: no lease, '
                        'glob, clamp, stop or slot end applies to it. For a robot whose operators are trusted')
    r.add_argument('--runs-dir', type=Path, help='where runs get their working directories '
                                                 '[$XDG_DATA_HOME/rosgate/runs]')
    r.add_argument('--max-runs', type=_at_least_one, default=d.max_runs, metavar='N',
                   help='runs going at once [%(default)s]')
    r.add_argument('--max-runs-per-person', type=_at_least_one, default=d.max_runs_per_person, metavar='N',
                   help='runs going at once for one signed-in person, admins excepted (with --auth) [%(default)s]')
    r.add_argument('--recordings-dir', type=Path, metavar='DIR',
                   help='where recordings made from the pages and /api/recordings go '
                        '[--record\'s DIR, else $XDG_DATA_HOME/rosgate/recordings]')
    r.add_argument('--record', type=Path, metavar='DIR',
                   help='record from start-up into DIR (also where /api/recordings keeps its files, '
                        'unless --recordings-dir says otherwise)')
    r.add_argument('--record-topics', metavar='GLOBS', help='topics --record takes, e.g. "[\'/turtle1/*\']" [all]')
    r.add_argument('--db', '--history-db', dest='db_url', metavar='URL',
                   help='where sign-in sessions, bookings and history are kept: an SQLAlchemy URL, e.g. '
                        'postgresql+psycopg://rosgate@dbhost/rosgate [sqlite:///$XDG_DATA_HOME/rosgate/rosgate.db]')
    h = p.add_argument_group('history and the twin')
    h.add_argument('--history', metavar='GLOBS',
                   help='topics whose numeric fields the gateway keeps, e.g. "[\'/s*/battery_state\', \'/turtle1/pose\']"; '
                        '"none" keeps nothing [every topic of type BatteryState, Temperature, Odometry or turtlesim Pose]')
    h.add_argument('--history-max-mb', type=float, default=d.history_max_mb, metavar='MB',
                   help='past this size in the store, the oldest history goes [%(default)s]')
    h.add_argument('--history-full-hours', type=float, default=d.history_full_hours, metavar='H',
                   help='history kept at full rate (1 Hz) this long, then as per-minute min/mean/max [%(default)s]')
    h.add_argument('--opcua', type=int, metavar='PORT',
                   help='serve the robots\' history fields and pose over OPC UA on this port (0: any free one)')
    h.add_argument('--urdf', type=Path, metavar='FILE',
                   help='the robot description the 3D twin draws (served at /urdf), in place of the '
                        'robot_description topic')
    h.add_argument('--mesh-path', type=Path, action='append', default=[], metavar='DIR',
                   help='a folder of description packages (DIR/PKG/meshes/...) whose files the twin loads '
                        'as package://PKG/..., besides AMENT_PREFIX_PATH\'s share folders (repeatable)')
    b.add_argument('--log-level', default='info', choices=('debug', 'info', 'warning', 'error'))
    robots.add_arguments(p)
    rules.add_arguments(p)
    return p


def _at_least_one(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'at least 1, not {value}')
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
    known = {f.name for f in fields(Settings)}
    values = {k: v for k, v in vars(args).items() if k in known}
    values['mesh_path'] = tuple(values.get('mesh_path') or ())
    extra = {k: v for k, v in vars(args).items() if k not in known}
    return Settings(**values, extra=extra)


def default_node_name(port: int, host: str | None = None) -> str:
    """``rosgate_<host>_<port>``: the same name at every start of a gateway, and different names
    for gateways on one graph (another port or another machine). A valid ROS node name: letters,
    digits and single underscores."""
    host = (host if host is not None else socket.gethostname()).split('.')[0]
    name = re.sub(r'[^A-Za-z0-9]+', '_', f'rosgate_{host}_{port}', flags=re.ASCII)
    return re.sub(r'_+', '_', name).strip('_')


def make_backend(args: argparse.Namespace, ros_args: list[str], node_name: str):
    choice = args.backend
    if choice == 'auto':
        try:
            import rclpy  # noqa: F401
            choice = 'rclpy'
        except ImportError:
            choice = 'sim'
    if choice == 'rclpy':
        return RclpyBackend(node_name=node_name, ros_args=ros_args, interfaces=tuple(args.interfaces),
                            interface_cache=args.interface_cache)
    return SimBackend(node_name=node_name, talker=args.talker,
                      fibonacci_interval=args.fibonacci_interval, robots=robots.specs_from_args(args))


def pages_box(base: str) -> str:
    """The pages' addresses framed, after the start-up line: with --fleet 30 the line came after
    some 60 lines of log and a teacher did not find it. The line above stays one line for scripts."""
    rows = [('IDE (students)', base), ('teleop (driving)', f'{base}teleop'), ('class (teacher)', f'{base}class')]
    lines = ['rosgate is ready. Open in a browser:', *(f'  {name:<17} {url}' for name, url in rows)]
    if '//localhost:' in base:
        lines.append('  (other machines: this machine\'s address in place of localhost)')
    rule = '=' * max(len(line) for line in lines)
    return '\n'.join(['', rule, *lines, rule, ''])


async def serve(settings: Settings, backend, sockets: list[socket.socket], *, announce=print) -> None:
    """Run the gateway on sockets already bound (``tornado.netutil.bind_sockets``)."""
    await backend.start()
    gateway = Gateway(settings, backend)
    rules.install(gateway, reads=rosapi.handles)
    app = make_app(gateway)
    gateway.count_clients()
    ssl_ctx = None
    if settings.certfile and settings.keyfile:
        ssl_ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        ssl_ctx.load_cert_chain(settings.certfile, settings.keyfile)
    server = tornado.httpserver.HTTPServer(app, ssl_options=ssl_ctx, max_buffer_size=settings.max_message_size * 4,
                                           body_timeout=settings.body_timeout,
                                           idle_connection_timeout=settings.idle_connection_timeout)
    server.add_sockets(sockets)
    port = sockets[0].getsockname()[1]
    host = settings.address if settings.address not in ('', '0.0.0.0', '::') else 'localhost'
    host = f'[{host}]' if ':' in host else host
    http, ws = ('https', 'wss') if ssl_ctx else ('http', 'ws')
    path = settings.url_path if settings.url_path.startswith('/') else '/' + settings.url_path
    problem = ide_problem(settings.ide_dir)
    base = f'{http}://{host}:{port}/'
    ide = (f'IDE {base} teleop {base}teleop class {base}class' if problem is None
           else f'IDE unavailable ({problem})')
    announce(f'rosgate: {ide} websocket {ws}://{host}:{port}{path} backend {backend.name} '
             f'node {backend.node_name}')
    if problem is None:
        announce(pages_box(base))

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await stop.wait()
    log.info('shutting down')
    server.stop()
    await gateway.shutdown()
    await backend.stop()
    await server.close_all_connections()


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
    # bound before the backend starts: the default node name holds the port (also when it is 0)
    sockets = tornado.netutil.bind_sockets(settings.port, settings.address or None)
    node_name = settings.node_name or default_node_name(sockets[0].getsockname()[1])
    settings = replace(settings, node_name=node_name)
    backend = make_backend(args, ros_args, node_name)
    try:
        asyncio.run(serve(settings, backend, sockets, announce=announce))
    except KeyboardInterrupt:
        pass
    return 0
