"""The backend contract: what the gateway needs from a ROS graph, in ROS terms.

Messages cross this interface as plain dicts in rosbridge shape (as produced by
``protocol.convert.from_json``): uint8[]/char[] as ``bytes``, other arrays as lists, Time and
Duration as ``{'sec', 'nanosec'}``. Types are full names (``pkg/msg/Name``). Every callback a
backend invokes runs on the gateway's IOLoop thread; the gateway never calls a backend from
another thread.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from protocol.msgdefs import ActionDef, MsgDef, SrvDef

Message = dict[str, Any]

# action_msgs/GoalStatus values
STATUS_UNKNOWN, STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING = 0, 1, 2, 3
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6

# How long a service call or a goal waits for a server that is not there yet, as rosbridge does
# (wait_for_service / wait_for_server with 1 s): a server a node has just created is not
# discovered at once. Measured through the rclpy gateway (Fast DDS, loopback-only namespace, 2
# cores), from creation to the answer: a new node of a running process 8-92 ms; a service of a
# process just started 3-1,324 ms, and half of 12 still undiscovered after 1 s (they fail, as on
# rosbridge; before this wait 9 of 12 failed within 9 ms).
SERVER_WAIT = 1.0


# action_msgs/srv/CancelGoal return codes
CANCEL_ERROR_NONE, CANCEL_ERROR_REJECTED, CANCEL_ERROR_UNKNOWN_GOAL_ID, CANCEL_ERROR_GOAL_TERMINATED = 0, 1, 2, 3


def is_hidden(name: str) -> bool:
    """A hidden ROS 2 name: one of its tokens starts with '_' (an action's ``/x/_action/status``), as
    rclpy's ``topic_or_service_is_hidden``; ROS 2's tools list these only when asked."""
    return any(token.startswith('_') for token in name.split('/'))


class BackendError(Exception):
    """The ROS side failed (blame: the graph, not the client): no such service, timeout, ..."""


class ServiceTimeout(BackendError):
    pass


@dataclass(frozen=True, slots=True)
class QoS:
    """The parts of a ROS 2 QoS profile rosbridge clients can ask for."""
    depth: int = 10
    reliable: bool = True
    transient_local: bool = False   # latched
    history_keep_all: bool = False
    deadline: float | None = None   # seconds
    lifespan: float | None = None   # seconds


class Handle(Protocol):
    def destroy(self) -> None: ...


class Subscription(Handle, Protocol):
    def want_cdr(self, wanted: bool) -> None:
        """Of a subscription made with ``cdr=True``: whether a consumer of the CDR is there now
        (cbor-raw, recordings). A backend for which the CDR as received costs extra keeps it only
        while wanted; the callback gets None otherwise."""


class Publisher(Handle, Protocol):
    topic: str
    type: str

    def publish(self, msg: Message) -> None: ...


@dataclass(slots=True)
class ActionResult:
    status: int             # STATUS_SUCCEEDED, STATUS_CANCELED or STATUS_ABORTED
    result: Message


class ClientGoal(Protocol):
    """A goal this gateway sent to an action server."""
    goal_id: str

    async def result(self) -> ActionResult: ...
    async def cancel(self) -> None: ...


class ServerGoal(Protocol):
    """A goal an action client sent to an action served through the gateway."""
    goal_id: str
    request: Message

    def publish_feedback(self, feedback: Message) -> None: ...
    def finish(self, status: int, result: Message) -> None: ...


@dataclass(slots=True)
class ActionServerCallbacks:
    on_goal: Callable[[ServerGoal], None]        # a new accepted goal
    on_cancel: Callable[[ServerGoal], None]      # a cancel request for a running goal


@dataclass(slots=True)
class NodeInfo:
    publishing: list[str] = field(default_factory=list)
    subscribing: list[str] = field(default_factory=list)
    services: list[str] = field(default_factory=list)


class Backend(Protocol):
    """One ROS graph. Implementations: backends.sim.SimBackend, backends.rclpy.RclpyBackend."""
    name: str            # 'sim' or 'rclpy'
    node_name: str       # the gateway's own node, e.g. '/rosgate'
    defs: Any            # has .msg(type) -> MsgDef (nested lookups of protocol.convert)

    async def start(self, batch_scope: Callable[[], Any] | None = None,
                    after_batch: Callable[[Callable[[], None]], bool] | None = None) -> None:
        """batch_scope: what a batch of messages is delivered inside (the bridge's ``corked``: each
        client's share in one write); after_batch(fn): whether fn runs at the end of the open batch
        (the bridge's ``after_batch``). None: each message on its own."""
    async def stop(self) -> None: ...

    # types
    def msg_def(self, type: str) -> MsgDef: ...             # raises protocol.msgdefs.UnknownType
    def srv_def(self, type: str) -> SrvDef: ...
    def action_def(self, type: str) -> ActionDef: ...
    def interfaces(self) -> list[str]: ...
    def typedefs(self, msg: MsgDef) -> list[dict]: ...        # rosapi TypeDef list, root first
    def full_text(self, msg: MsgDef) -> str: ...
    def to_cdr(self, type: str, msg: Message) -> bytes: ...   # for cbor-raw and Foxglove clients
    def from_cdr(self, type: str, data: bytes) -> Message:
        """A message dict from CDR bytes (a Foxglove client's message or service request);
        ``type`` a message type or a service's part ('pkg/srv/X_Request', as ``to_cdr`` takes
        too). ConversionError when the bytes are not that type's CDR."""

    # topics
    def create_publisher(self, topic: str, type: str, qos: QoS) -> Publisher: ...
    def subscribe(self, topic: str, type: str, callback: Callable[..., None], qos: QoS | None = None, *,
                  cdr: bool = False) -> Subscription:
        """qos None: adapt to the publishers present (latched if they all are). cdr: the callback
        is ``callback(msg, cdr)`` with the message's CDR as received where the backend has it
        (else None), instead of ``callback(msg)``."""

    def latched(self, topic: str) -> bool:
        """True when every publisher of the topic is transient-local (a latched topic)."""

    def latched_messages(self, topic: str) -> list[Message] | None:
        """What a new transient-local subscriber would receive now, or None if unknown."""

    # services
    async def wait_for_service(self, service: str, timeout: float) -> list[str]:
        """The types of the service's servers, once there is one; [] if none within timeout s."""
    async def call_service(self, service: str, type: str, request: Message, timeout: float) -> Message:
        """Raises BackendError (no such service within SERVER_WAIT, the server failed) or
        ServiceTimeout."""
    def advertise_service(self, service: str, type: str,
                          handler: Callable[[Message], Awaitable[Message]]) -> Handle:
        """handler raises BackendError to fail the call."""

    # actions
    async def send_goal(self, action: str, type: str, goal: Message,
                        on_feedback: Callable[[Message], None] | None) -> ClientGoal:
        """Returns once the goal is accepted; raises BackendError when rejected or no server
        within SERVER_WAIT."""
    def advertise_action(self, action: str, type: str, callbacks: ActionServerCallbacks) -> Handle: ...

    # graph introspection (names are absolute; types full)
    def topics(self, hidden: bool = False) -> list[tuple[str, str]]:
        """hidden: also the hidden topics (``is_hidden``), e.g. an action's ``_action/status``."""
    def services(self, hidden: bool = False) -> list[tuple[str, str]]:
        """hidden: also the hidden services, e.g. an action's ``_action/cancel_goal``."""
    def actions(self) -> list[tuple[str, str]]: ...
    def nodes(self) -> list[str]: ...
    def node_info(self, node: str) -> NodeInfo: ...
    def publishers(self, topic: str) -> list[str]: ...
    def subscribers(self, topic: str) -> list[str]: ...
    def service_providers(self, service: str) -> list[str]: ...

    # parameters of any node ('/node', 'param'); values are Python bool/int/float/str/list
    async def get_param(self, node: str, name: str) -> Any: ...          # KeyError if not set
    async def set_param(self, node: str, name: str, value: Any) -> None: ...
    async def delete_param(self, node: str, name: str) -> None: ...
    async def param_names(self) -> list[str]: ...                       # ['/node:param', ...]

    def now(self) -> tuple[int, int]: ...                                # (sec, nanosec)
