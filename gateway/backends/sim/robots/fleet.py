"""Stations (one namespace, one world, its robots) and the fleet of namespaced stations.

With ``--fleet N`` the gateway runs N stations, ``/s01`` .. ``/sNN``, each with its own world and
its own copy of every selected robot (``/s07/turtle1/cmd_vel``, ``/s07/spawn``, ``/s07/cmd_vel``,
``/s07/world/markers``, ...). The ``/fleet`` node's parameter ``namespaces`` lists them. Who may use
which station is the gateway's business, not the robots': the gateway hands stations out to people
(``/fleet/claim``, see ``gateway/rules/stations.py``).
The robots enforce nothing: with --exclusive-control the gateway lets only the station's person drive it.
"""

from __future__ import annotations

from . import markers as mk
from .rover import Rover
from .turtlesim import Turtlesim
from .world import World


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
    """The stations' names, for anyone who asks the graph (see the module docstring)."""

    def __init__(self, graph, namespaces: list[str]):
        self.graph, self.namespaces = graph, namespaces
        self.node = graph.node('fleet')
        self.node.declare_parameter('namespaces', list(namespaces))

    def destroy(self) -> None:
        self.node.destroy()
