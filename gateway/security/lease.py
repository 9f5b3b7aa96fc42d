"""The driver lease (``--exclusive-control``): one client at a time commands the robot.

Command names are topics of the velocity types plus anything matching ``--control-glob``
(topics, services, actions). The first client to command takes the lease; others are refused
with a status error and can watch. The holder gives it back by disconnecting or by publishing
"release" to /rosgate/control (its motion is stopped first); "take" takes a free lease, and an
admin (anyone, when --auth is off) takes it over from its holder, whose motion is stopped. Who
drives is published, latched, on /rosgate/driver as a JSON text: {"driver": null} or
{"driver": {"client", "name", "role", "remote", "since"}}.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from fnmatch import fnmatchcase

from protocol.errors import ProtocolError

from ..backends.base import QoS

CONTROL_TOPIC = '/rosgate/control'
DRIVER_TOPIC = '/rosgate/driver'
STRING = 'std_msgs/msg/String'


def who(session) -> str:
    name = session.attrs.get('name')
    return f'{name} (client {session.id})' if name else f'client {session.id}'


class Lease:
    def __init__(self, gateway, *, types: frozenset[str], globs: tuple[str, ...] | None,
                 takeover_role: str | None, on_lost: Callable[[object], None]):
        self.gateway, self.types, self.globs = gateway, types, globs or ()
        self.takeover_role, self.on_lost = takeover_role, on_lost
        self.holder = None
        self.since = 0.0
        backend = gateway.backend
        self._driver = backend.create_publisher(DRIVER_TOPIC, STRING, QoS(depth=1, transient_local=True))
        # declares the control topic so clients may publish to it without a type
        self._control = backend.subscribe(CONTROL_TOPIC, STRING, lambda msg: None)
        self._announce()

    def is_command(self, name: str, type: str | None = None) -> bool:
        return type in self.types or any(fnmatchcase(name, g) for g in self.globs)

    def require(self, session, name: str, type: str | None = None) -> None:
        """Grant a free lease to a commanding client; refuse everyone but the holder."""
        if not self.is_command(name, type) or self.holder is session:
            return
        if self.holder is None:
            self._grant(session)
            return
        raise ProtocolError(f'{name}: {who(self.holder)} is driving (exclusive control); watch, wait for '
                            f'"release", or ask an admin to take over')

    def publish_hook(self, session, pub, msg):
        if pub.topic == CONTROL_TOPIC:
            self._command(session, str(msg.get('data', '')).strip().lower())
            return None
        self.require(session, pub.topic, pub.type)
        return msg

    def _command(self, session, word: str) -> None:
        if word == 'release':
            if self.holder is session:
                self._grant(None)
            return
        if word != 'take':
            raise ProtocolError(f'{CONTROL_TOPIC} takes "take" or "release", not {word!r}')
        if self.holder is None or self.holder is session:
            self._grant(session)
        elif self.takeover_role is None or session.attrs.get('role') == self.takeover_role:
            self._grant(session)
        else:
            raise ProtocolError(f'{who(self.holder)} is driving; only an admin can take over')

    def _grant(self, session) -> None:
        previous, self.holder, self.since = self.holder, session, time.time()
        if previous is not None and previous is not session and not previous.closed:
            self.on_lost(previous)   # whoever gives up the lease, or loses it, stops moving
            if session is not None:
                previous.status('warning', f'{who(session)} took over the driver lease; your commands were stopped')
        if session is not None:
            session.status('info', f'you hold the driver lease as client {session.id}')
        self._announce()

    def on_close(self, session) -> None:
        if self.holder is session:
            self.holder = None
            self._announce()

    def _announce(self) -> None:
        h = self.holder
        driver = None if h is None else {
            'client': h.id, 'name': h.attrs.get('name') or f'client {h.id}', 'role': h.attrs.get('role'),
            'remote': h.remote, 'since': round(self.since, 3)}
        self._driver.publish({'data': json.dumps({'driver': driver})})
