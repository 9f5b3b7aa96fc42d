"""An in-process ROS-like graph on the IOLoop: nodes, topics, services, actions, parameters.

No threads: everything runs on the loop that owns the graph. Messages are plain dicts in
rosbridge shape and are treated as immutable once published (subscribers share one object).
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import itertools
import logging
import time
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from protocol.msgdefs import Definitions, normalize
from protocol.names import name_problem

from .. import blame
from ..base import (
    STATUS_ABORTED, STATUS_SUCCEEDED, SERVER_WAIT, ActionServerCallbacks, BackendError, QoS, ServiceTimeout,
    is_hidden,
)
from .actions import SimActionServer, SimClientGoal, SimServerGoal
from .params import ParameterServices

__all__ = ['Graph', 'Node', 'SimActionServer', 'SimClientGoal', 'SimServerGoal', 'resolve']

from .timers import SimTimer, Ticker

log = logging.getLogger('rosgate.sim')
Message = dict[str, Any]


def checked(node: Node, name: str, kind: str) -> str:
    """``name`` resolved in ``node``'s namespace, if rcl would take it as a topic's, service's or
    action's, else a BackendError saying why (what ROS 2 refuses is never created and listed)."""
    full = resolve(name, node.namespace) if name else ''
    problem = name_problem(full) or (name.endswith('/') and 'a name does not end with /') or None
    if problem is not None:
        raise BackendError(f'{name[:100]!r} is no valid ROS 2 {kind} name: {problem}')
    return full


def resolve(name: str, namespace: str = '/') -> str:
    """Absolute ROS name: 'cmd_vel' in namespace '/turtle1' -> '/turtle1/cmd_vel'."""
    if not name:
        raise ValueError('empty ROS name')
    if name.startswith('/'):
        return name.rstrip('/') or '/'
    return (namespace.rstrip('/') + '/' + name).rstrip('/')


@dataclass(eq=False)
class Topic:
    name: str
    type: str
    publishers: list[SimPublisher] = field(default_factory=list)
    subscriptions: list[SimSubscription] = field(default_factory=list)
    latched: deque = field(default_factory=lambda: deque(maxlen=1))

    def retained(self) -> list[Message]:
        """What a late transient-local subscriber receives now, oldest first (a retained
        callable is called for its message: a snapshot built only when someone joins; one past
        its publisher's QoS lifespan is no longer given)."""
        now = time.monotonic()
        out = []
        for m in self.latched:
            if isinstance(m, Lasting):
                if m.until < now:
                    continue
                m = m.msg
            out.append(m() if callable(m) else m)
        return out


class Lasting:
    """A retained message of a publisher with a QoS lifespan (ROS 2's /rosout: 10 s), until when."""

    __slots__ = ('msg', 'until')

    def __init__(self, msg, until: float):
        self.msg, self.until = msg, until


class SimPublisher:
    def __init__(self, node: Node, topic: Topic, qos: QoS):
        self.node, self._topic, self.qos = node, topic, qos
        self.topic, self.type = topic.name, topic.type
        if qos.transient_local and topic.latched.maxlen < qos.depth:
            topic.latched = deque(topic.latched, maxlen=max(1, qos.depth))

    def publish(self, msg: Message) -> None:
        topic = self._topic
        if self.qos.transient_local:
            topic.latched.append(Lasting(msg, time.monotonic() + self.qos.lifespan) if self.qos.lifespan else msg)
        for sub in tuple(topic.subscriptions):
            if sub.backlog:   # a newcomer gets the retained messages before this newer one
                sub.catch_up()
            try:
                sub.callback(msg)
            except Exception:  # a faulty subscriber must not break the publisher
                log.exception('subscription callback on %s failed', topic.name)

    @property
    def subscription_count(self) -> int:
        """How many subscriptions the topic has (costly messages can be skipped at 0)."""
        return len(self._topic.subscriptions)

    def retain(self, msg: Message | Callable[[], Message]) -> None:
        """Replace what late subscribers of a latched topic receive, without sending it now.

        ``msg`` may be a callable returning the message, called each time a subscriber joins."""
        self._topic.latched.append(msg)

    def destroy(self) -> None:
        self.node.graph._remove_endpoint(self._topic, self, 'publishers')
        self.node._owned.discard(self)


class SimSubscription:
    def __init__(self, node: Node, topic: Topic, callback: Callable[[Message], None], qos: QoS | None):
        self.node, self._topic, self.callback, self.qos = node, topic, callback, qos
        self.topic, self.type = topic.name, topic.type
        self.backlog: deque[Message] = deque()   # retained messages not yet handed to the callback

    def catch_up(self) -> None:
        """Hand over the retained messages this subscription joined with, oldest first."""
        while self.backlog and self in self._topic.subscriptions:
            try:
                self.callback(self.backlog.popleft())
            except Exception:  # as in publish: a faulty subscriber must not break the others
                log.exception('subscription callback on %s failed', self.topic)

    def want_cdr(self, wanted: bool) -> None:
        """The sim holds messages as dicts: there is no CDR as received to keep."""

    def destroy(self) -> None:
        self.node.graph._remove_endpoint(self._topic, self, 'subscriptions')
        self.node._owned.discard(self)


@dataclass(eq=False)
class SimService:
    node: Node
    name: str
    type: str
    handler: Callable[[Message], Any]

    def destroy(self) -> None:
        graph = self.node.graph
        if graph._services.get(self.name) is self:
            del graph._services[self.name]
            aside = graph._yielded.pop(self.name, None)   # a demo's service that stepped aside comes back
            if aside is not None:
                graph._services[self.name] = aside
                graph._created('service', self.name)
        self.node._owned.discard(self)


class Node:
    """A node of the sim graph. Robots, demo servers and the gateway itself are nodes."""

    def __init__(self, graph: Graph, name: str, namespace: str = '/'):
        self.graph, self.namespace = graph, namespace
        self.name = resolve(name, namespace)
        self.params: dict[str, Any] = {}
        self.param_descriptions: dict[str, dict] = {}   # name -> {description, constraints, read_only}
        self._param_hooks: dict[str, Callable[[Any], None]] = {}
        self._owned: set = set()
        # a demo node's services step aside for another node's of the same name (the ROS 2 tutorial's
        # /add_two_ints served from the IDE page), and come back when it goes
        self.yields = False
        self._tasks: set[asyncio.Task] = set()
        self._timers: set[SimTimer] = set()

    def resolve(self, name: str) -> str:
        return resolve(name, self.namespace)

    # topics
    def create_publisher(self, topic: str, type: str, qos: QoS = QoS()) -> SimPublisher:
        pub = SimPublisher(self, self.graph._topic(checked(self, topic, 'topic'), type), qos)
        pub._topic.publishers.append(pub)
        self._owned.add(pub)
        return pub

    def create_subscription(self, topic: str, type: str, callback: Callable[[Message], None],
                            qos: QoS | None = None) -> SimSubscription:
        t = self.graph._topic(checked(self, topic, 'topic'), type)
        sub = SimSubscription(self, t, callback, qos)
        t.subscriptions.append(sub)
        self._owned.add(sub)
        if (qos is None or qos.transient_local) and t.latched:
            # not now: the caller does not hold the handle yet. A publish before then hands
            # these over first, so a retained message never follows a newer live one.
            sub.backlog.extend(t.retained())
            self.graph.loop.call_soon(sub.catch_up)
        return sub

    # services
    def create_service(self, name: str, type: str, handler: Callable[[Message], Any]) -> SimService:
        name = checked(self, name, 'service')
        type = self.graph.defs.srv(type).type   # also an action's X_SendGoal, X_GetResult
        old = self.graph._services.get(name)
        if old is not None and old.node is not self:
            if not old.node.yields:
                raise BackendError(f'service {name} is already provided by {old.node.name}')
            self.graph._yielded[name] = old
        svc = SimService(self, name, type, handler)
        self.graph._services[name] = svc
        self._owned.add(svc)
        self.graph._created('service', name)
        return svc

    # actions
    def create_action_server(self, name: str, type: str, callbacks: ActionServerCallbacks) -> SimActionServer:
        name = checked(self, name, 'action')
        type = normalize(type, 'action')
        self.graph.defs.action(type)
        old = self.graph._actions.get(name)
        if old is not None:
            raise BackendError(f'action {name} is already served by {old.node.name}')
        server = SimActionServer(self, name, type, callbacks)   # with its hidden endpoints
        self.graph._actions[name] = server
        self._owned.add(server)
        self.graph._created('action', name)
        return server

    def create_simple_action_server(self, name: str, type: str,
                                    execute: Callable[[SimServerGoal], Awaitable[Message]]) -> SimActionServer:
        """An action server whose goals each run ``execute(goal)`` as a task.

        ``execute`` returns the result; it should check ``goal.cancel_requested`` and call
        ``goal.finish(STATUS_CANCELED, result)`` itself when it honours a cancel.
        """
        def on_goal(goal: SimServerGoal) -> None:
            self.spawn(self._run_goal(goal, execute))

        return self.create_action_server(name, type, ActionServerCallbacks(on_goal, lambda goal: None))

    async def _run_goal(self, goal: SimServerGoal, execute) -> None:
        try:
            result = await execute(goal)
            goal.finish(STATUS_SUCCEEDED, result)
        except asyncio.CancelledError:
            goal.finish(STATUS_ABORTED, self.graph.default_result(goal.server.type))
            raise
        except Exception as e:
            if blame.answerable(e):   # the client's goal was wrong (e.g. out of range): no traceback
                log.warning('action %s aborted a goal: %s', goal.server.name, blame.sentence(e))
            else:                     # a bug of the action server
                log.exception('action %s failed', goal.server.name)
            goal.finish(STATUS_ABORTED, self.graph.default_result(goal.server.type))

    # parameters
    def declare_parameter(self, name: str, value: Any, on_set: Callable[[Any], None] | None = None,
                          **description) -> None:
        """description: what describe_parameters says of it (description, constraints, read_only)."""
        self.params[name] = value
        if description:
            self.param_descriptions[name] = description
        if on_set:
            self._param_hooks[name] = on_set

    def set_parameter(self, name: str, value: Any) -> None:
        old = self.params.get(name)
        if old is not None and value is not None and type(old) is not type(value) and not (
                isinstance(old, float) and isinstance(value, int) and not isinstance(value, bool)):
            raise BackendError(f'parameter {name} of {self.name} is a {type(old).__name__}, '
                               f'not a {type(value).__name__}')
        if isinstance(old, float) and isinstance(value, int):
            value = float(value)
        self.params[name] = value
        hook = self._param_hooks.get(name)
        if hook:
            hook(value)

    # tasks and timers
    def spawn(self, coro) -> asyncio.Task:
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    def create_timer(self, period: float, callback: Callable[[], Any]) -> SimTimer:
        """``callback`` now (soon) and every ``period`` s after, with the graph's other timers of
        that period (``Ticker``)."""
        timer = self.graph.ticker(period).add(self, callback)
        self._timers.add(timer)
        return timer

    def destroy(self) -> None:
        for timer in list(self._timers):
            timer.cancel()
        for task in list(self._tasks):
            task.cancel()
        for entity in list(self._owned):
            entity.destroy()
        self.graph._nodes.pop(self.name, None)


class Graph:
    def __init__(self, defs: Definitions | None = None):
        self.defs = defs or Definitions.jazzy()
        self._tickers: dict[float, Ticker] = {}
        # what publishing in a batch (a tick) runs inside: the gateway's corked(), set through the backend
        self.batch_scope: Callable[[], Any] = contextlib.nullcontext
        self._topics: dict[str, Topic] = {}
        self._services: dict[str, SimService] = {}
        self._actions: dict[str, SimActionServer] = {}
        self._yielded: dict[str, SimService] = {}    # a demo's services stepped aside (Node.yields)
        self._nodes: dict[str, Node] = {}
        self._ids = itertools.count(1)
        self._waiting: dict[tuple[str, str], list[asyncio.Future]] = {}   # (kind, name) -> callers

    def ticker(self, period: float) -> Ticker:
        t = self._tickers.get(period)
        if t is None:
            t = self._tickers[period] = Ticker(self, period)
        return t

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        return asyncio.get_running_loop()

    def node(self, name: str, namespace: str = '/') -> Node:
        node = Node(self, name, namespace)
        if node.name in self._nodes:
            raise BackendError(f'a node named {node.name} already exists')
        self._nodes[node.name] = node
        ParameterServices(node)   # as every ROS 2 node: <node>/get_parameters, set_parameters, ...
        return node

    def default_result(self, action_type: str) -> Message:
        from protocol.convert import default_message
        return default_message(self.defs, self.defs.action(action_type).result)

    # --- endpoints ---------------------------------------------------------------------------

    def _topic(self, name: str, type: str) -> Topic:
        type = self.defs.msg(type).type   # also an action's X_FeedbackMessage
        topic = self._topics.get(name)
        if topic is None:
            topic = self._topics[name] = Topic(name, type)
        elif topic.type != type:
            raise BackendError(f'topic {name} has type {topic.type}, not {type}')
        return topic

    def _remove_endpoint(self, topic: Topic, endpoint, kind: str) -> None:
        items = getattr(topic, kind)
        if endpoint in items:
            items.remove(endpoint)
        if not topic.publishers and not topic.subscriptions and self._topics.get(topic.name) is topic:
            del self._topics[topic.name]

    # --- clients -----------------------------------------------------------------------------

    def _created(self, kind: str, name: str) -> None:
        for waiter in self._waiting.pop((kind, name), ()):
            if not waiter.done():
                waiter.set_result(None)

    async def _server(self, kind: str, name: str, timeout: float | None):
        """The service or action server of name, waiting up to timeout s for one to be created."""
        table = self._services if kind == 'service' else self._actions
        server = table.get(name)
        if server is None and timeout:
            waiter = self.loop.create_future()
            waiters = self._waiting.setdefault((kind, name), [])
            waiters.append(waiter)
            try:
                await asyncio.wait_for(waiter, timeout)
            except asyncio.TimeoutError:
                pass
            finally:
                if waiter in waiters:
                    waiters.remove(waiter)
                    if not waiters and self._waiting.get((kind, name)) is waiters:
                        del self._waiting[(kind, name)]
            server = table.get(name)
        return server

    async def wait_for_service(self, name: str, timeout: float | None) -> SimService | None:
        return await self._server('service', name, timeout)

    async def call_service(self, name: str, request: Message, timeout: float | None) -> Message:
        wait = SERVER_WAIT if timeout is None else min(timeout, SERVER_WAIT)
        svc = await self._server('service', name, wait)
        if svc is None:
            raise BackendError(f'service {name} is not available')
        try:
            result = svc.handler(request)
            if inspect.isawaitable(result):
                result = await asyncio.wait_for(result, timeout)
        except asyncio.TimeoutError:
            raise ServiceTimeout(f'service {name} did not answer within {timeout} s') from None
        except BackendError:
            raise
        except Exception as e:
            log.exception('service %s failed', name)
            raise BackendError(f'service {name} failed: {e}') from e
        return result

    async def send_goal(self, name: str, type: str, request: Message,
                        on_feedback: Callable[[Message], None] | None) -> SimClientGoal:
        """A goal of action type ``type``: refused when the server's type differs (on a ROS 2
        graph no server of the goal's type would answer it)."""
        type = normalize(type, 'action')
        server = await self._server('action', name, SERVER_WAIT)
        if server is None:
            raise BackendError(f'action server {name} is not available')
        if server.type != type:
            raise BackendError(f'action {name} has type {server.type}, not {type}')
        return SimClientGoal(server.accept(request, on_feedback=on_feedback))

    # --- introspection -----------------------------------------------------------------------

    def topics(self, hidden: bool = False) -> list[tuple[str, str]]:
        return sorted((t.name, t.type) for t in self._topics.values() if hidden or not is_hidden(t.name))

    def topic_entries(self) -> list[Topic]:
        """Every topic with its publishers and subscriptions (each has a .node)."""
        return list(self._topics.values())

    def services(self, hidden: bool = False) -> list[tuple[str, str]]:
        return sorted((s.name, s.type) for s in self._services.values() if hidden or not is_hidden(s.name))

    def actions(self) -> list[tuple[str, str]]:
        return sorted((a.name, a.type) for a in self._actions.values())

    def nodes(self) -> list[str]:
        return sorted(self._nodes)

    def get_node(self, name: str) -> Node:
        try:
            return self._nodes[resolve(name)]
        except (KeyError, ValueError):
            raise BackendError(f'no node named {name}') from None

    def endpoints(self, topic: str, kind: str) -> list[str]:
        t = self._topics.get(topic)
        return sorted({e.node.name for e in getattr(t, kind)}) if t else []

    def service_node(self, name: str) -> str | None:
        svc = self._services.get(name)
        return svc.node.name if svc else None
