"""What the rclpy backend answers from its type definitions and from the graph: message, service
and action definitions, the graph's topics, services, actions and nodes, and parameters through
the target node's rcl_interfaces services. A part of ``backend.RclpyBackend`` (its base class),
which holds ``node``, ``defs`` and ``convert``."""

from __future__ import annotations

from typing import Any

from protocol.errors import ConversionError
from protocol.msgdefs import ActionDef, MsgDef, SrvDef, normalize

from . import params as rclpy_params
from ..base import BackendError, Message, NodeInfo, is_hidden
from .entities import fq_name, split_node


class TypesAndGraph:
    # --- types --------------------------------------------------------------------------------

    def msg_def(self, type: str) -> MsgDef:
        found = self.defs.derived(type)   # an action's X_FeedbackMessage
        return found if isinstance(found, MsgDef) else self.defs.msg(normalize(type, 'msg'))

    def srv_def(self, type: str) -> SrvDef:
        return self.defs.srv(type)

    def action_def(self, type: str) -> ActionDef:
        return self.defs.action(type)

    def interfaces(self) -> list[str]:
        return self.defs.interfaces()

    def typedefs(self, msg: MsgDef) -> list[dict]:
        return self.defs.typedefs(msg)

    def full_text(self, msg: MsgDef) -> str:
        return self.defs.full_text(msg)

    def to_cdr(self, type: str, msg: Message) -> bytes:
        from rclpy.serialization import serialize_message  # noqa: PLC0415
        cls = self._cdr_class(type)
        if getattr(cls, 'raw_only', False):     # described by the graph: no class
            return self.convert.cdr_writer(cls)(msg)
        return serialize_message(self.convert.from_dict(cls, msg))

    def from_cdr(self, type: str, data: bytes) -> Message:
        """The gateway's CDR reader where it compiles one (as the pump takes topics), else rclpy's."""
        from rclpy.serialization import deserialize_message  # noqa: PLC0415
        cls = self._cdr_class(type)
        read = self.convert.cdr_reader(cls)
        if read is not None:
            try:
                return read(bytes(data))
            except Exception as e:  # noqa: BLE001 (cdr.Slow, or bytes the fast path cannot read: rclpy decides)
                if getattr(cls, 'raw_only', False):   # described by the graph: no class to read with
                    raise ConversionError(f'cannot deserialize {type}: {e}') from None
        try:
            return self.convert.to_dict(deserialize_message(bytes(data), cls))
        except Exception as e:  # noqa: BLE001 (rclpy's words for malformed CDR vary)
            raise ConversionError(f'cannot deserialize {type}: {e}') from None

    def _cdr_class(self, type: str):
        """The class of a message type, or of a service's part ('pkg/srv/X_Request')."""
        parts = type.strip('/').split('/')
        if len(parts) == 3 and parts[1] == 'srv':
            whole, _, part = parts[2].rpartition('_')
            if whole and part in ('Request', 'Response'):
                return getattr(self.defs.srv_class(f'{parts[0]}/srv/{whole}'), part)
        return self.defs.msg_class(type)

    # --- graph --------------------------------------------------------------------------------

    def topics(self, hidden: bool = False) -> list[tuple[str, str]]:
        return sorted((n, t[0]) for n, t in self.node.get_topic_names_and_types()
                      if t and (hidden or not is_hidden(n)))

    def served_types(self) -> dict[str, list[str]]:
        """Services with a server (clients alone make a name appear in the graph too)."""
        return {n: t for n, t in self.node.get_service_names_and_types()
                if t and self.node.count_services(n)}

    def services(self, hidden: bool = False) -> list[tuple[str, str]]:
        return sorted((n, t[0]) for n, t in self.served_types().items() if hidden or not is_hidden(n))

    def actions(self) -> list[tuple[str, str]]:
        """Actions with a server: a server publishes the action's status topic, clients do not."""
        from rclpy.action import get_action_names_and_types  # noqa: PLC0415
        return sorted((n, t[0]) for n, t in get_action_names_and_types(self.node)
                      if t and self.node.count_publishers(f'{n}/_action/status'))

    def nodes(self) -> list[str]:
        return sorted({fq_name(ns, n) for n, ns in self.node.get_node_names_and_namespaces()})

    def node_info(self, node: str) -> NodeInfo:
        name, ns = split_node(node)
        try:
            pubs = self.node.get_publisher_names_and_types_by_node(name, ns)
            subs = self.node.get_subscriber_names_and_types_by_node(name, ns)
            srvs = self.node.get_service_names_and_types_by_node(name, ns)
        except Exception as e:  # rclpy's NodeNameNonExistentError
            raise BackendError(f'no node named {node}') from e
        return NodeInfo(sorted(n for n, _ in pubs), sorted(n for n, _ in subs), sorted(n for n, _ in srvs))

    def publishers(self, topic: str) -> list[str]:
        return sorted({fq_name(i.node_namespace, i.node_name)
                       for i in self.node.get_publishers_info_by_topic(topic)})

    def subscribers(self, topic: str) -> list[str]:
        return sorted({fq_name(i.node_namespace, i.node_name)
                       for i in self.node.get_subscriptions_info_by_topic(topic)})

    def service_providers(self, service: str) -> list[str]:
        providers = []
        for name, ns in self.node.get_node_names_and_namespaces():
            try:
                services = self.node.get_service_names_and_types_by_node(name, ns)
            except Exception:  # noqa: BLE001 (the node left meanwhile)
                continue
            if any(s == service for s, _ in services):
                providers.append(fq_name(ns, name))
        return sorted(set(providers))

    def action_servers(self, action: str) -> list[str]:
        from rclpy.action import get_action_server_names_and_types_by_node  # noqa: PLC0415
        servers = []
        for name, ns in self.node.get_node_names_and_namespaces():
            try:
                actions = get_action_server_names_and_types_by_node(self.node, name, ns)
            except Exception:  # noqa: BLE001 (the node left meanwhile)
                continue
            if any(a == action for a, _ in actions):
                servers.append(fq_name(ns, name))
        return sorted(set(servers))

    # --- parameters (through the target node's rcl_interfaces services) ------------------------

    async def get_param(self, node: str, name: str) -> Any:
        return await rclpy_params.get_param(self, node, name)

    async def set_param(self, node: str, name: str, value: Any) -> None:
        await rclpy_params.set_param(self, node, name, value)

    async def delete_param(self, node: str, name: str) -> None:
        await rclpy_params.delete_param(self, node, name)

    async def param_names(self) -> list[str]:
        return await rclpy_params.param_names(self)

    async def param_call(self, node: str, suffix: str, srv_cls, request):
        """Call ``<node>/<suffix>`` (an rcl_interfaces service) with a ROS request object."""
        node = '/' + node.strip('/')
        service = f'{node}/{suffix}'
        if not self.node.count_services(service):
            raise BackendError(f'no node named {node} with parameter services')
        type = f'rcl_interfaces/srv/{srv_cls.__name__}'
        return await self._call(service, type, srv_cls, request, self.service_timeout)

    def now(self) -> tuple[int, int]:
        return self.node.get_clock().now().seconds_nanoseconds()
