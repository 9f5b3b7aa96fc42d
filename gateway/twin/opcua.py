"""The twin over OPC UA (``--opcua PORT``), for the industrial clients a plant already runs.

A second face of the gateway, beside the history: it reads what the history takes from the bridge
(one listener on ``History``, no subscription of its own) and never publishes. Its address space,
under ``Objects/Robots`` (namespace ``urn:rosgate:twin``):

- a folder per robot namespace (``s01``, ``s02``, ...; ``robot`` for topics outside any station),
- inside, a folder per topic (``battery_state``, ``motor/left/temperature`` as nested folders) and
  a read-only Double variable per kept field (``percentage``, ``temperature``, ...),
- ``pose``: ``x``, ``y``, ``yaw`` from the namespace's odometry (or its turtle's pose),

each updated as the history takes a point (about once a second), with the point's time as its
source timestamp. No variable is writable, whoever asks.

Security: with ``--auth`` a client signs in with a user name and its token as the password
(``UserName`` identity); the token must be that user's, and each role that may subscribe may read
(every role). Anonymous sessions are refused then. The token never crosses the network as given: the server has a
self-signed certificate of its own (made once in the data directory, ``opcua/``) and clients
encrypt the token with it on the plain (``None``) channel, or use the signed and encrypted
``Basic256Sha256`` channel. Without ``--auth`` the channel is ``None`` only: everything it serves
is readable by anyone who reaches the port.

The server is asyncua's, on a thread of its own (``Twin``).
"""

from __future__ import annotations

import asyncio
import logging
import os
import socket
import threading
from datetime import datetime, timezone

from ..rules.access import may
from ..auth.tokens import AuthError
from ..settings import data_dir
from ..rules.hooks import Hook
from .ports import SignIn

log = logging.getLogger('rosgate.opcua')
NAMESPACE = 'urn:rosgate:twin'
APP_URI = 'urn:rosgate:server'
PUSH_EVERY = 0.25       # s between batches of value writes
POSE = {   # the topic's last name -> its fields that make the robot's pose
    'odom': {'pose.pose.position.x': 'x', 'pose.pose.position.y': 'y', 'yaw': 'yaw'},
    'pose': {'x': 'x', 'y': 'y', 'theta': 'yaw'},   # a turtle's
}
ROOT_FOLDER = 'robot'


def split(topic: str, stations: tuple[str, ...]) -> tuple[str, list[str]]:
    """('s01', ['battery_state']) for /s01/battery_state when /s01 is a station; else ('robot', [...])."""
    for ns in stations:
        if topic.startswith(ns + '/'):
            return ns.strip('/'), topic[len(ns) + 1:].split('/')
    return ROOT_FOLDER, topic.strip('/').split('/')


class Twin(Hook):
    """The OPC UA server on a thread and event loop of its own: asyncua builds its standard
    address space in pure Python at start (about ten seconds of one core on a busy machine), which
    on the gateway's loop would stall every client meanwhile. Points cross over in one dict
    under a lock, taken in batches. ``policy``: who signs in (its ``auth``; None: nobody), the
    stations; ``address``: the gateway's --address."""

    def __init__(self, history, port: int, *, policy: SignIn, address: str = ''):
        self.history, self.port, self.policy = history, port, policy
        self.auth = policy.auth
        self.host = address or '0.0.0.0'
        self.shown = address or 'localhost'
        self.server = None
        self.nodes: dict[tuple, object] = {}    # folder path or (folder path, field) -> asyncua Node
        self.dirty: dict[tuple[str, str], tuple[float, float]] = dict(history.latest)
        self.lock = threading.Lock()
        self.stations: tuple[str, ...] = ()     # the fleet's stations, copied over by the gateway's loop
        self.loop: asyncio.AbstractEventLoop | None = None
        self.stopping: asyncio.Event | None = None
        self.address: str | None = None
        self.thread = threading.Thread(target=self._run, name='rosgate-opcua', daemon=True)

    def start(self) -> None:
        self.thread.start()

    def on_history_point(self, topic: str, field: str, t: float, v: float) -> None:
        """On the gateway's loop, from the history (rules.hooks)."""
        stations = self.policy.stations
        if stations is not None:
            self.stations = tuple(stations.stations())
        with self.lock:
            self.dirty[(topic, field)] = (t, v)

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except Exception:
            log.exception('OPC UA server failed')

    async def _serve(self) -> None:
        from asyncua import Server, ua     # there: the start-up check refused --opcua without it
        logging.getLogger('asyncua').setLevel(logging.WARNING)   # it logs each node it makes at INFO
        self.loop, self.stopping, self.ua = asyncio.get_running_loop(), asyncio.Event(), ua
        server = Server(user_manager=_Users(self.policy) if self.auth is not None else None)
        await server.init()
        server.set_endpoint(f'opc.tcp://{self.host}:{self.port}/rosgate/')
        server.set_server_name('rosgate twin')
        await server.set_application_uri(APP_URI)
        if self.auth is not None:   # the tokens go encrypted with the server's key, even on a plain channel
            await self._certificate(server)
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity,
                                        ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt])
        else:
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        server.set_identity_tokens([ua.UserNameIdentityToken] if self.auth is not None else [ua.AnonymousIdentityToken])
        self.ns = await server.register_namespace(NAMESPACE)
        self.nodes[()] = await server.nodes.objects.add_folder(self.ns, 'Robots')
        await server.start()
        self.server = server
        self.address = f'opc.tcp://{self.shown}:{server.bserver.port}/rosgate/'
        log.info('OPC UA: %s (%s)', self.address, 'user name and token' if self.auth is not None else 'anonymous')
        try:
            while not self.stopping.is_set():
                try:
                    await asyncio.wait_for(self.stopping.wait(), PUSH_EVERY)
                except asyncio.TimeoutError:
                    pass
                with self.lock:
                    batch, self.dirty = self.dirty, {}
                for (topic, field), (t, v) in batch.items():
                    try:
                        await self._write(topic, field, t, v)
                    except Exception:
                        log.exception('OPC UA: cannot show %s %s', topic, field)
        finally:
            await server.stop()

    async def _certificate(self, server) -> None:
        """The server's own self-signed certificate and key, made once in the data directory."""
        from asyncua.crypto.cert_gen import setup_self_signed_certificate
        from cryptography.x509.oid import ExtendedKeyUsageOID

        folder = data_dir('opcua')
        folder.mkdir(parents=True, exist_ok=True)
        key, cert = folder / 'key.pem', folder / 'cert.der'
        host = socket.gethostname()
        await setup_self_signed_certificate(key, cert, APP_URI, host, [ExtendedKeyUsageOID.SERVER_AUTH],
                                            {'commonName': f'rosgate twin on {host}'})
        os.chmod(key, 0o600)
        await server.load_certificate(str(cert))
        await server.load_private_key(str(key))

    async def _write(self, topic: str, field: str, t: float, v: float) -> None:
        robot, parts = split(topic, self.stations)
        await self._set((robot, *parts), field, t, v)
        pose = POSE.get(parts[-1], {})
        if field in pose:
            await self._set((robot, 'pose'), pose[field], t, v)

    async def _set(self, folder_path: tuple, name: str, t: float, v: float) -> None:
        ua = self.ua
        key = (folder_path, name)
        node = self.nodes.get(key)
        if node is None:
            folder = await self._folder(folder_path)
            node = self.nodes[key] = await folder.add_variable(self.ns, name, 0.0, varianttype=ua.VariantType.Double)
        value = ua.DataValue(ua.Variant(float(v), ua.VariantType.Double), SourceTimestamp=_utc(t),
                             ServerTimestamp=_utc(t))
        await self.server.write_attribute_value(node.nodeid, value)

    async def _folder(self, path: tuple):
        node = self.nodes.get(path)
        if node is None:
            parent = await self._folder(path[:-1])
            node = self.nodes[path] = await parent.add_folder(self.ns, path[-1])
        return node

    def on_shutdown(self) -> None:
        if self.loop is not None and self.stopping is not None:
            self.loop.call_soon_threadsafe(self.stopping.set)
            self.thread.join(10)


def _utc(t: float) -> datetime:
    return datetime.fromtimestamp(t, tz=timezone.utc)


class _Users:
    """asyncua's user manager: the user name and a token of that user, as with --auth elsewhere."""

    def __init__(self, policy: SignIn):
        self.policy = policy

    def get_user(self, iserver, username=None, password=None, certificate=None):
        from asyncua.crypto.permission_rules import User, UserRole

        if not username or not password:
            log.info('OPC UA: a session without user name and token was refused')
            return None
        try:
            identity = self.policy.auth.token(f'opcua:{username[:64]}', password)
        except AuthError as e:
            log.info('OPC UA: %s refused: %s', username[:64], e)
            return None
        if identity.name != username or may(self.policy, identity, 'subscribe') is not None:
            log.info('OPC UA: %s refused: the token is not theirs', username[:64])
            return None
        return User(role=UserRole.User, name=identity.name)


def start_twin(history, port: int | None, *, policy: SignIn, address: str = '') -> Twin | None:
    """The OPC UA server with --opcua (the start-up check refused it without asyncua, or with
    --history none)."""
    if port is None:
        return None
    twin = Twin(history, port, policy=policy, address=address)   # a part of the gateway's hooks (server.start)
    twin.start()
    return twin
