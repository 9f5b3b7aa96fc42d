"""Stations (one namespace, one world, its robots) and the fleet of namespaced stations.

With ``--fleet N`` the gateway runs N stations, ``/s01`` .. ``/sNN``, each with its own world and
its own copy of every selected robot (``/s07/turtle1/cmd_vel``, ``/s07/spawn``, ``/s07/cmd_vel``,
``/s07/world/markers``, ...). A client claims one by calling ``/fleet/claim``
(std_srvs/srv/Trigger): ``success`` true and ``message`` the namespace, e.g. "/s07", the lowest
one neither claimed nor in use; ``success`` false when all are taken. It gives it back with
``<namespace>/fleet/release`` (std_srvs/srv/Trigger), or the teacher frees all with
``/fleet/release_all`` (std_srvs/srv/Empty). A station is "in use" while a client publishes on
one of its topics or subscribes to one other than ``world/markers`` and ``rosgate/program`` (the
teacher's overview of all stations watches those); a claim lapses once its station has not been in use for ``CLAIM_GRACE`` seconds.
The ``/fleet`` node's parameters ``namespaces`` and ``claimed`` list the stations and the claims.
Nothing is enforced: the teacher (and anyone) sees and can drive every station.
"""

from __future__ import annotations

import time

from . import markers as mk
from .rover import Rover
from .turtlesim import Turtlesim
from .world import World

CLAIM_GRACE = 60.0
CHECK_PERIOD = 5.0


class FramedHub:
    """A MarkerHub whose markers are in another frame: two robots of one station that live in
    different worlds (turtlesim's square and the rover's arena) share one ``world/markers`` and
    a viewer draws one frame at a time."""

    def __init__(self, hub: mk.MarkerHub, frame: str):
        self.hub, self.frame = hub, frame

    def __getattr__(self, name):
        return getattr(self.hub, name)

    def _framed(self, m: dict) -> dict:
        m['header'] = {**m['header'], 'frame_id': self.frame}
        return m

    def set_static(self, m: dict) -> None:
        self.hub.set_static(self._framed(m))

    def update(self, m: dict) -> None:
        self.hub.update(self._framed(m))

    def add_pen(self, m: dict) -> None:
        self.hub.add_pen(self._framed(m))

    def add_layer(self, layer) -> None:
        self.hub.add_layer(lambda: [self._framed(m) for m in layer()])


class Station:
    """The robots of one namespace sharing one world view (``world/markers``)."""

    def __init__(self, graph, namespace: str, kinds: tuple[str, ...], world: World, *,
                 speed: float = 1.0, twist_stamped: bool = False):
        self.namespace = namespace
        self.view = graph.node('world_view', namespace)
        self.hub = mk.MarkerHub(self.view)
        self.robots: list = []
        several = len(kinds) > 1     # then each robot's world is its own frame: one world per view
        try:
            for kind in kinds:
                if kind == 'turtlesim':
                    hub = FramedHub(self.hub, 'turtlesim') if several else self.hub
                    self.robots.append(Turtlesim(graph, hub, namespace, speed=speed))
                elif kind == 'rover':
                    self.robots.append(Rover(graph, self.hub, world, namespace, speed=speed,
                                             twist_stamped=twist_stamped))
                else:
                    raise ValueError(f'unknown robot kind {kind!r}')
        except Exception:
            self.destroy()
            raise
        self.hub.flush()

    def destroy(self) -> None:
        for robot in self.robots:
            robot.destroy()
        self.robots = []
        self.view.destroy()


class Fleet:
    """Hands out stations to clients (see the module docstring)."""

    def __init__(self, graph, namespaces: list[str]):
        self.graph, self.namespaces = graph, namespaces
        self.claims: dict[str, float] = {}       # namespace -> last time it was claimed or in use
        self.node = graph.node('fleet')
        self.node.declare_parameter('namespaces', list(namespaces))
        self.node.declare_parameter('claimed', [])
        self.node.create_service('/fleet/claim', 'std_srvs/srv/Trigger', self.on_claim)
        self.node.create_service('/fleet/release_all', 'std_srvs/srv/Empty', self.on_release_all)
        for ns in namespaces:
            self.node.create_service(f'{ns}/fleet/release', 'std_srvs/srv/Trigger',
                                     lambda req, ns=ns: self.on_release(ns))
        self.node.create_timer(CHECK_PERIOD, self.expire)

    def destroy(self) -> None:
        self.node.destroy()

    def in_use(self, namespace: str) -> bool:
        """Whether a node outside the station publishes on one of its topics or subscribes to
        one (other than the world view and the program report, which the teacher's view watches)."""
        prefix = namespace + '/'
        watched = (prefix + 'world/markers', prefix + 'rosgate/program')
        for topic in self.graph.topic_entries():
            if topic.name.startswith(prefix):
                endpoints = topic.publishers if topic.name in watched else (*topic.publishers, *topic.subscriptions)
                if any(not e.node.name.startswith(prefix) for e in endpoints):
                    return True
        return False

    def on_claim(self, req: dict) -> dict:
        for ns in self.namespaces:
            if ns not in self.claims and not self.in_use(ns):
                self.claims[ns] = time.monotonic()
                self._publish_claims()
                return {'success': True, 'message': ns}
        return {'success': False, 'message': f'all {len(self.namespaces)} stations are claimed or in use'}

    def on_release(self, ns: str) -> dict:
        if self.claims.pop(ns, None) is None:
            return {'success': False, 'message': f'{ns} was not claimed'}
        self._publish_claims()
        return {'success': True, 'message': ns}

    def on_release_all(self, req: dict) -> dict:
        self.claims.clear()
        self._publish_claims()
        return {}

    def expire(self) -> None:
        now = time.monotonic()
        for ns, since in list(self.claims.items()):
            if self.in_use(ns):
                self.claims[ns] = now
            elif now - since > CLAIM_GRACE:
                del self.claims[ns]
                self._publish_claims()

    def _publish_claims(self) -> None:
        self.node.params['claimed'] = sorted(self.claims)
