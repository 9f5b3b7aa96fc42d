"""The sim backend: the Backend contract over the in-process graph."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from protocol.msgdefs import ActionDef, Definitions, MsgDef, SrvDef, normalize

from ..base import ActionServerCallbacks, BackendError, Handle, NodeInfo, QoS
from .actions import clock
from .demo import start_demo_nodes
from .graph import Graph, Node, SimClientGoal, SimPublisher, resolve

Message = dict[str, Any]


class SimBackend:
    name = 'sim'

    def __init__(self, *, node_name: str = 'rosgate', demo: bool = True, talker: bool = False,
                 fibonacci_interval: float = 1.0, robots: tuple = (), defs: Definitions | None = None):
        self.graph = Graph(defs)
        self.node_name = resolve(node_name)
        self._demo, self._talker, self._fib_interval = demo, talker, fibonacci_interval
        self._robot_specs = robots
        self._node: Node | None = None
        self.robots: list = []

    async def start(self, batch_scope=None, after_batch=None) -> None:
        """batch_scope: what a timer's tick publishes inside (the bridge's ``corked``: timers.Ticker)."""
        if batch_scope is not None:
            self.graph.batch_scope = batch_scope
        self._node = self.graph.node(self.node_name)
        if self._demo:
            start_demo_nodes(self.graph, talker=self._talker, fibonacci_interval=self._fib_interval)
        for spec in self._robot_specs:
            self.robots.append(await spec(self.graph))

    async def stop(self) -> None:
        for node in list(self.graph._nodes.values()):
            node.destroy()

    @property
    def defs(self) -> Definitions:
        return self.graph.defs

    @property
    def node(self) -> Node:
        assert self._node is not None, 'SimBackend.start() first'
        return self._node

    # --- types -------------------------------------------------------------------------------
    def msg_def(self, type: str) -> MsgDef:
        return self.graph.defs.msg(type)

    def srv_def(self, type: str) -> SrvDef:
        return self.graph.defs.srv(type)

    def action_def(self, type: str) -> ActionDef:
        return self.graph.defs.action(type)

    def interfaces(self) -> list[str]:
        return self.graph.defs.interfaces()

    def typedefs(self, msg: MsgDef) -> list[dict]:
        return self.graph.defs.typedefs(msg)

    def full_text(self, msg: MsgDef) -> str:
        return self.graph.defs.full_text(msg)

    def to_cdr(self, type: str, msg: Message) -> bytes:
        from protocol.convert import to_cdr
        return to_cdr(self.graph.defs, type, msg)

    def from_cdr(self, type: str, data: bytes) -> Message:
        from protocol.convert import from_cdr
        return from_cdr(self.graph.defs, type, bytes(data))

    # --- topics ------------------------------------------------------------------------------
    def create_publisher(self, topic: str, type: str, qos: QoS) -> SimPublisher:
        return self.node.create_publisher(topic, type, qos)

    def subscribe(self, topic: str, type: str, callback: Callable[..., None],
                  qos: QoS | None = None, *, cdr: bool = False) -> Handle:
        if cdr:   # the sim holds messages as dicts: there is no CDR as received
            return self.node.create_subscription(topic, type, lambda msg: callback(msg, None), qos)
        return self.node.create_subscription(topic, type, callback, qos)

    def latched(self, topic: str) -> bool:
        t = self.graph._topics.get(topic)
        return bool(t and t.publishers and all(p.qos.transient_local for p in t.publishers))

    def latched_messages(self, topic: str) -> list[Message]:
        """What a new transient-local subscriber receives now (the topic's retained messages)."""
        t = self.graph._topics.get(topic)
        return t.retained() if t else []

    # --- services ----------------------------------------------------------------------------
    async def wait_for_service(self, service: str, timeout: float) -> list[str]:
        svc = await self.graph.wait_for_service(resolve(service), timeout)
        return [svc.type] if svc is not None else []

    async def call_service(self, service: str, type: str, request: Message, timeout: float) -> Message:
        return await self.graph.call_service(resolve(service), request, timeout)

    def advertise_service(self, service: str, type: str,
                          handler: Callable[[Message], Awaitable[Message]]) -> Handle:
        svc = self.graph._services.get(resolve(service))
        if svc is not None and svc.node is self.node:
            svc.destroy()  # re-advertising replaces
        return self.node.create_service(service, type, handler)

    # --- actions -----------------------------------------------------------------------------
    async def send_goal(self, action: str, type: str, goal: Message,
                        on_feedback: Callable[[Message], None] | None) -> SimClientGoal:
        return await self.graph.send_goal(resolve(action), type, goal, on_feedback)

    def advertise_action(self, action: str, type: str, callbacks: ActionServerCallbacks) -> Handle:
        return self.node.create_action_server(action, type, callbacks)

    # --- introspection -----------------------------------------------------------------------
    def topics(self, hidden: bool = False) -> list[tuple[str, str]]:
        return self.graph.topics(hidden)

    def services(self, hidden: bool = False) -> list[tuple[str, str]]:
        return self.graph.services(hidden)

    def actions(self) -> list[tuple[str, str]]:
        return self.graph.actions()

    def nodes(self) -> list[str]:
        return self.graph.nodes()

    def node_info(self, node: str) -> NodeInfo:
        n = self.graph.get_node(node)
        info = NodeInfo()
        for t in self.graph._topics.values():
            if any(p.node is n for p in t.publishers):
                info.publishing.append(t.name)
            if any(s.node is n for s in t.subscriptions):
                info.subscribing.append(t.name)
        info.services = sorted(s.name for s in self.graph._services.values() if s.node is n)
        return info

    def publishers(self, topic: str) -> list[str]:
        return self.graph.endpoints(topic, 'publishers')

    def subscribers(self, topic: str) -> list[str]:
        return self.graph.endpoints(topic, 'subscriptions')

    def service_providers(self, service: str) -> list[str]:
        node = self.graph.service_node(resolve(service))
        return [node] if node else []

    # --- parameters --------------------------------------------------------------------------
    async def get_param(self, node: str, name: str) -> Any:
        params = self.graph.get_node(node).params
        if name not in params:
            raise KeyError(f'{node}:{name}')
        return params[name]

    async def set_param(self, node: str, name: str, value: Any) -> None:
        self.graph.get_node(node).set_parameter(name, value)

    async def delete_param(self, node: str, name: str) -> None:
        n = self.graph.get_node(node)
        if name not in n.params:
            raise KeyError(f'{node}:{name}')
        del n.params[name]

    async def param_names(self) -> list[str]:
        return sorted(f'{n.name}:{p}' for n in self.graph._nodes.values() for p in n.params)

    def now(self) -> tuple[int, int]:
        return clock()


def check_type(kind: str, type: str) -> str:
    """Normalise a type name; BackendError for a malformed one."""
    try:
        return normalize(type, kind)
    except LookupError as e:
        raise BackendError(str(e)) from None
