"""The rclpy backend: the gateway as one node of a real ROS 2 (Jazzy) graph.

rclpy is imported when the backend starts, so importing this module works without ROS. One node
(``rosgate`` by default; ROS arguments such as ``--ros-args -r __node:=x`` honoured). Topic
subscriptions, service clients and services served by the gateway are moved by the pump
(``pump``): one thread with its own rcl wait set that hands what it takes to the IOLoop in
batches; the loop publishes and sends requests and responses itself. Actions go through a
SingleThreadedExecutor in a thread of its own: their callbacks that wait for the gateway are
coroutines in a reentrant callback group, hold no thread while they wait, and the loop wakes the
executor when their answer is there. No thread logs except through a hop to the loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Awaitable, Callable
from typing import Any

from protocol.msgdefs import normalize

from ..base import SERVER_WAIT, ActionServerCallbacks, BackendError, Message, QoS, ServiceTimeout
from .actions import RclpyActionServer, send_goal
from .build import Builder
from .entities import Held, RclpyPublisher, RclpyService, RclpySubscription, ros_qos
from .graphtypes import GraphTypes
from .pump import Pump, ServiceCaller, ServiceServer, TopicReader
from .queries import TypesAndGraph
from .types import Converter, RosDefinitions

log = logging.getLogger('rosgate.rclpy')

# requests in flight per service: a server's request reader keeps the last 10 (the default
# service QoS), so a larger burst would lose requests
IN_FLIGHT = 8
# history of the gateway's own subscriptions: the loop may publish a burst of a client's messages
# before the pump takes the first (they share the GIL); a history of 10 lost most of 32 in flight
READER_DEPTH = 100
TAKE_EVERY = 32     # a client's burst is taken from the gateway's readers at least this often
COOL = 0.005        # seconds without the gateway publishing before the pump waits on a topic again
UNHELD_FOR = 10.0   # seconds a topic stays with the pump once the middleware delivered late


class RclpyBackend(TypesAndGraph):
    """Backend over rclpy. ``ros_args``: ROS arguments (``['--ros-args', '-r', '__ns:=/robot']``);
    None reads them from ``sys.argv``. ``service_timeout``: how long a ROS caller of a service
    served by the gateway waits for its answer, and a goal for its acceptance. ``interfaces``:
    directories of ``<pkg>/<kind>/<Name>.<kind>`` texts for services and actions the install lacks,
    built on first use into ``interface_cache`` (``build``)."""

    name = 'rclpy'

    def __init__(self, node_name: str = 'rosgate', *, ros_args: list[str] | None = None,
                 service_timeout: float = 5.0, interfaces: tuple = (), interface_cache=None):
        self.node_name = '/' + node_name.strip('/')
        self.service_timeout = service_timeout
        self.defs = RosDefinitions(tuple(interfaces))
        self.builder = Builder(self.defs, interface_cache)
        self.convert = Converter(self.defs)
        self._args = None if ros_args is None else ['rosgate', *ros_args]
        self.loop: asyncio.AbstractEventLoop | None = None
        self.node = self.reentrant = None
        self._context = self._executor = self._thread = None
        self.pump: Pump | None = None
        self._rclpy = None      # rclpy's C extension (rcl entities the pump waits on)
        self._clients: dict[tuple[str, str], ServiceCaller] = {}
        self._in_flight: dict[str, asyncio.Semaphore] = {}
        self._action_clients: dict[tuple[str, str], Any] = {}
        self._served: dict[str, RclpyService] = {}
        self._action_servers: dict[str, RclpyActionServer] = {}
        self._closing: dict[str, RclpyActionServer] = {}
        self.readers: dict[str, list[TopicReader]] = {}   # the gateway's subscriptions by topic
        self._round = False     # the loop has a take scheduled for the end of this round
        self._held: dict[str, Held] = {}        # topics whose readers the loop takes from
        self._unheld: dict[str, float] = {}     # topic -> loop time before which it is not held
        self._last: dict[str, float] = {}       # topic -> loop time the gateway last published to it
        # the pump delivers each batch of messages inside this (the gateway: one write per client)
        self.batch_scope: Callable[[], Any] = contextlib.nullcontext
        # fn -> whether fn runs at the end of the gateway's open batch (the frames of one socket
        # read); False: no batch is open (both given to ``start``)
        self.after_batch: Callable[[Callable[[], None]], bool] = lambda fn: False

    # --- lifecycle ----------------------------------------------------------------------------

    async def start(self, batch_scope=None, after_batch=None) -> None:
        """batch_scope, after_batch: the bridge's (``bridge.outbox``), so each client gets a batch's
        frames in one write; None: each message on its own."""
        if batch_scope is not None:
            self.batch_scope = batch_scope
        if after_batch is not None:
            self.after_batch = after_batch
        import rclpy  # noqa: PLC0415 (optional dependency, present on ROS 2 machines)
        from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: PLC0415
        from rclpy.context import Context  # noqa: PLC0415
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
        from rclpy.impl.implementation_singleton import rclpy_implementation  # noqa: PLC0415
        from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

        self.loop = asyncio.get_running_loop()
        self._rclpy = rclpy_implementation
        self._context = Context()
        # the gateway handles SIGINT/SIGTERM itself (closing clients first), so rclpy must not
        rclpy.init(args=self._args, context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(self.node_name.lstrip('/'), context=self._context)
        self.node_name = self.node.get_fully_qualified_name()
        self.reentrant = ReentrantCallbackGroup()
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name='rosgate-rclpy', daemon=True)
        self._thread.start()
        self.defs.graph = GraphTypes(self.node, self._thread, self.defs)    # types the install lacks
        self.pump = Pump(self._context, self.loop, scope=lambda: self.batch_scope())
        self.pump.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception as e:  # noqa: BLE001 (external shutdown ends the spin)
            self.hop(self.report, 'executor stopped', e)

    async def stop(self) -> None:
        if self.node is None:
            return
        for served in list(self._served.values()):
            served.destroy()
        for server in list(self._action_servers.values()):
            server.destroy()
        await asyncio.to_thread(self._shutdown)

    def _shutdown(self) -> None:
        executor, node, context, thread = self._executor, self.node, self._context, self._thread
        self.node = None
        self.pump.stop()
        executor.shutdown(timeout_sec=2.0)
        thread.join(timeout=2.0)
        node.destroy_node()
        context.try_shutdown()

    # --- threads ------------------------------------------------------------------------------

    def hop(self, fn: Callable, *args) -> None:
        """Run ``fn(*args)`` on the loop (from any thread)."""
        try:
            self.loop.call_soon_threadsafe(fn, *args)
        except RuntimeError:
            pass  # the loop is closed: the gateway is gone

    def wake(self) -> None:
        """Resume executor tasks waiting in ``Pending`` (from any thread).

        A task re-checks its future on every executor wake-up; the second wake covers a task that
        was between its check and its yield when the first came.
        """
        self._wake_executor()
        self.hop(self.loop.call_later, 0.05, self._wake_executor)

    def _wake_executor(self) -> None:
        executor = self._executor
        if executor is not None and self.node is not None:
            executor.wake()

    def wrap(self, future) -> asyncio.Future:
        """An rclpy Future as an asyncio Future of the loop."""
        result = self.loop.create_future()

        def settle(f) -> None:
            if result.done():
                return
            if f.cancelled():
                result.cancel()
            elif f.exception() is not None:
                result.set_exception(f.exception())
            else:
                result.set_result(f.result())

        future.add_done_callback(lambda f: self.hop(settle, f))
        return result

    @staticmethod
    def report(what: str, error: BaseException) -> None:
        log.warning('%s: %s', what, error)

    async def _until(self, ready: Callable[[], bool], timeout: float) -> bool:
        """Wait for discovery (a new server in the graph, a new client matched with its server):
        rclpy has no event for it, and its own wait_for_service sleeps 0.25 s between looks. The
        loop looks again after 1, 2, 4, ... ms, at most 50 ms apart. False: not within timeout s."""
        deadline, delay = self.loop.time() + timeout, 0.001
        while not ready():
            left = deadline - self.loop.time()
            if left <= 0:
                return False
            await asyncio.sleep(min(delay, left))
            delay = min(delay * 2, 0.05)
        return True

    # --- entities -----------------------------------------------------------------------------

    def _entity(self, kind: str, cls, name: str, profile=None):
        """An rcl Subscription, Client or Service of the node for the pump (services and their
        clients with ROS's service QoS); loading the type support first turns a type whose
        support is missing into a clear error."""
        from rclpy.qos import qos_profile_services_default  # noqa: PLC0415
        from rclpy.type_support import check_is_valid_msg_type, check_is_valid_srv_type  # noqa: PLC0415

        (check_is_valid_msg_type if kind == 'Subscription' else check_is_valid_srv_type)(cls)
        profile = profile if profile is not None else qos_profile_services_default
        with self.node.handle:
            return getattr(self._rclpy, kind)(self.node.handle, cls, name, profile.get_c_qos_profile())


    # --- topics -------------------------------------------------------------------------------

    def _topic(self, topic: str, type: str) -> tuple[str, str, Any]:
        full = self.msg_def(type).type
        topic = self.node.resolve_topic_name(topic)
        for name, types in self.node.get_topic_names_and_types():
            if name == topic and full not in types:
                raise BackendError(f'topic {topic} has type {types[0]}, not {full}')
        return topic, full, self.defs.msg_class(full)

    def create_publisher(self, topic: str, type: str, qos: QoS) -> RclpyPublisher:
        topic, full, cls = self._topic(topic, type)
        return RclpyPublisher(self, topic, full, cls, self.node.create_publisher(cls, topic, ros_qos(qos)))

    def subscribe(self, topic: str, type: str, callback: Callable[..., None],
                  qos: QoS | None = None, *, cdr: bool = False) -> RclpySubscription:
        topic, full, cls = self._topic(topic, type)
        handle = RclpySubscription(self, topic, full, callback, cdr)
        sub = self._entity('Subscription', cls, topic, ros_qos(qos if qos is not None else self._adapted_qos(topic)))
        handle.sub = TopicReader(sub, cls, self.convert.to_dict, handle.deliver,
                                 lambda e: self.report(f'subscription {topic}', e),
                                 self.convert.cdr_reader(cls))
        self.pump.add(handle.sub)
        self.readers.setdefault(topic, []).append(handle.sub)
        if topic in self._held:
            self.pump.hold([handle.sub])
        return handle

    def published(self, topic: str) -> None:
        """The gateway published on topic: its own subscriptions of it hold the message now.

        Fast DDS delivers to a process's own readers inside the publish call, so the loop
        takes them itself: at the first message of a round of the loop (a lone message goes
        out at once), then every TAKE_EVERY messages and at the end of the round, in one batch;
        while the gateway handles the frames of one socket read, the round ends with that batch
        (``after_batch``: what is taken goes out with the batch's frames, one write per client).
        While the gateway keeps publishing to a topic (a message within COOL seconds of the one
        before), the pump stops waiting on its readers (``Pump.hold``): it would wake for each
        message and find nothing. A ROS node's messages on the topic are taken along, and
        within 2 x COOL seconds of the gateway's last message the pump waits on the readers
        again. A middleware that delivers later (a take finds fewer messages than were
        published) leaves the topic to the pump.

        Measured (64 KiB, 32 in flight, three paired runs): 4,326-4,656 msg/s and 215-230 µs
        of gateway CPU a message, against 2,811-3,301 and 319-375 µs with one take per round
        and the pump waiting on every reader; 64 B: 14.9-18.9k against 13.8-14.8k msg/s."""
        readers = self.readers.get(topic)
        if not readers:
            return
        held = self._held.get(topic)
        if held is None:
            now = self.loop.time()
            last, self._last[topic] = self._last.get(topic, -COOL), now
            if now - last >= COOL or now < self._unheld.get(topic, now):
                if not self._round:     # the pump takes the rest of this round
                    self._start_round()
                    self.pump.take_here(readers)
                return
            self._unheld.pop(topic, None)
            held = self._held[topic] = Held()
            self.pump.hold(readers)
            self.loop.call_later(COOL, self._cool, topic, held)
        held.busy = True
        held.owed += 1
        if not self._round:
            self._start_round()
            self._take(topic, held)
        elif held.owed >= TAKE_EVERY:
            self._take(topic, held)

    def _start_round(self) -> None:
        """The take at the end of this round: at the end of the gateway's batch when one is open
        (the frames of one socket read: what it takes goes out with the batch's frames, in the
        same write), else at the end of this turn of the loop. The caller still takes the first
        message at once: inside a batch its frames wait for the batch's write, and a take that
        finds less than was published tells that the middleware delivers later (the pump then
        takes the topic; taken only at the batch's end, the late messages of a burst would wait
        for the next round, 5 ms and more: measured 64 KiB at 32 in flight, half the rate)."""
        self._round = True
        if not self.after_batch(self._round_end):
            self.loop.call_soon(self._round_end)

    def _round_end(self) -> None:
        self._round = False
        for topic, held in list(self._held.items()):
            if held.owed:
                self._take(topic, held)

    def _take(self, topic: str, held: Held) -> None:
        taken = self.pump.take_here(self.readers.get(topic, []))
        if taken is None:       # published from inside a delivery: taken at the end of the round
            return
        if taken < held.owed:   # this middleware delivers later: the pump takes this topic
            self._unhold(topic, held)
            self._unheld[topic] = self.loop.time() + UNHELD_FOR
        held.owed = 0

    def _cool(self, topic: str, held: Held) -> None:
        if self._held.get(topic) is not held or self.node is None:
            return
        if held.busy:
            held.busy = False
            self.loop.call_later(COOL, self._cool, topic, held)
        else:
            self._unhold(topic, held)

    def _unhold(self, topic: str, held: Held) -> None:
        if self._held.get(topic) is held:
            del self._held[topic]
            self.pump.release(self.readers.get(topic, []))

    def _adapted_qos(self, topic: str) -> QoS:
        """Transient-local if every publisher is, best-effort if any publisher is."""
        from rclpy.qos import ReliabilityPolicy  # noqa: PLC0415

        infos = self.node.get_publishers_info_by_topic(topic)
        best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
        return QoS(depth=READER_DEPTH, reliable=not best_effort, transient_local=self.latched(topic, infos))

    def latched(self, topic: str, infos=None) -> bool:
        """Whether every publisher of the topic is transient-local (and there is one)."""
        from rclpy.qos import DurabilityPolicy  # noqa: PLC0415

        if infos is None:
            infos = self.node.get_publishers_info_by_topic(self.node.resolve_topic_name(topic))
        return bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                   for i in infos)

    def latched_messages(self, topic: str) -> None:
        """DDS keeps what transient-local publishers retain; the gateway cannot read it back."""
        return None

    # --- services -----------------------------------------------------------------------------

    def _client(self, service: str, type: str, cls) -> ServiceCaller:
        client = self._clients.get((service, type))
        if client is None:
            handle = self._entity('Client', cls, service)
            client = self._clients[(service, type)] = ServiceCaller(handle, cls)
            self.pump.add(client)
        return client

    async def _call(self, service: str, type: str, cls, request, timeout: float | None):
        client = self._client(service, type, cls)
        handle = client.handle
        limit = self._in_flight.setdefault(service, asyncio.Semaphore(IN_FLIGHT))
        timeout = timeout if timeout and timeout > 0 else None
        wait = timeout or self.service_timeout
        try:
            async with asyncio.timeout(timeout), limit:
                if not await self._until(handle.service_server_is_available, wait):
                    raise ServiceTimeout(f'service {service} did not become ready within {wait} s')
                future = self.loop.create_future()
                with handle:
                    sequence = handle.send_request(request)
                client.pending[sequence] = future    # the pump's answer reaches the loop after this
                try:
                    return await future
                finally:
                    client.pending.pop(sequence, None)
        except TimeoutError:
            raise ServiceTimeout(f'service {service} did not answer within {timeout} s') from None

    async def call_service(self, service: str, type: str, request: Message, timeout: float) -> Message:
        full = self.defs.srv(type).type   # also an action's X_SendGoal, X_GetResult
        cls = await self.builder.cls(full, 'srv', timeout, service)
        service = self.node.resolve_service_name(service)
        client = self._clients.get((service, full))
        # a client matched with a server needs no look at the graph: DDS matches only equal types
        if client is None or not client.handle.service_server_is_available():
            wait = SERVER_WAIT if not timeout else min(timeout, SERVER_WAIT)
            types = await self.wait_for_service(service, wait)
            if not types:
                raise BackendError(f'service {service} is not available')
            if full not in types:
                raise BackendError(f'service {service} has type {types[0]}, not {full}')
        response = await self._call(service, full, cls, self.convert.from_dict(cls.Request, request), timeout)
        return self.convert.to_dict(response)

    async def wait_for_service(self, service: str, timeout: float) -> list[str]:
        service = self.node.resolve_service_name(service)
        await self._until(lambda: self.node.count_services(service) > 0, timeout)
        return self.served_types().get(service, [])

    def advertise_service(self, service: str, type: str,
                          handler: Callable[[Message], Awaitable[Message]]) -> RclpyService:
        full = normalize(type, 'srv')
        self.defs.srv(full)
        cls = self.defs.srv_class(full)
        service = self.node.resolve_service_name(service)
        old = self._served.get(service)
        if old is not None:
            old.destroy()    # re-advertising replaces
        elif service in self.served_types():
            others = [p for p in self.service_providers(service) if p != self.node_name]
            if others:
                raise BackendError(f'service {service} is already provided by {", ".join(others)}')
        handle = RclpyService(self, service, full, cls, handler)
        srv = self._entity('Service', cls, service)
        handle.srv = handle.entity = ServiceServer(srv, cls, handle.on_request)
        self.pump.add(handle.srv)
        self._served[service] = handle
        return handle

    def destroy_quietly(self, destroy: Callable, entity) -> None:
        """Destroy an entity later on; the node may be gone by then."""
        if self.node is not None:
            try:
                destroy(entity)
            except Exception as e:  # noqa: BLE001
                log.debug('destroying %s: %s', entity, e)

    async def serve(self, service: str, handler, request: Message) -> Message | None:
        """On the loop: the gateway's answer, or None (the ROS caller then gets a default response)."""
        try:
            return await asyncio.wait_for(handler(request), self.service_timeout)
        except asyncio.TimeoutError:
            log.warning('service %s: no response within %s s', service, self.service_timeout)
        except BackendError as e:
            log.warning('service %s failed: %s', service, e)
        except Exception:
            log.exception('service %s failed', service)
        return None

    # --- actions ------------------------------------------------------------------------------

    async def send_goal(self, action: str, type: str, goal: Message,
                        on_feedback: Callable[[Message], None] | None):
        from rclpy.action import ActionClient  # noqa: PLC0415

        full = normalize(type, 'action')
        self.defs.action(full)
        action = self.node.resolve_service_name(action)
        status = f'{action}/_action/status'     # published by an action's servers only
        await self._until(lambda: self.node.count_publishers(status) > 0, SERVER_WAIT)
        served = dict(self.actions()).get(action)
        if served is None:
            raise BackendError(f'action server {action} is not available')
        if served != full:   # before building a class of the goal's type: no server would take it
            raise BackendError(f'action {action} has type {served}, not {full}')
        cls = await self.builder.cls(full, 'action', None, action)
        client = self._action_clients.get((action, full))
        if client is None:
            client = ActionClient(self.node, cls, action, callback_group=self.reentrant)
            self._action_clients[(action, full)] = client
        if not await self._until(client.server_is_ready, self.service_timeout):
            raise BackendError(f'action server {action} did not become ready')
        return await send_goal(self, action, client, cls, goal, on_feedback, self.service_timeout)

    def advertise_action(self, action: str, type: str, callbacks: ActionServerCallbacks) -> RclpyActionServer:
        full = normalize(type, 'action')
        self.defs.action(full)
        cls = self.defs.action_class(full)
        action = self.node.resolve_service_name(action)
        if action in self._action_servers:
            raise BackendError(f'action {action} is already served by this gateway')
        others = [n for n in self.action_servers(action) if n != self.node_name]
        if others:
            raise BackendError(f'action {action} is already served by {", ".join(others)}')
        closing = self._closing.pop(action, None)
        if closing is not None:
            closing.close()
        server = RclpyActionServer(self, action, full, cls, callbacks)
        self._action_servers[action] = server
        return server

    def forget_action_server(self, server: RclpyActionServer) -> None:
        """The server stops taking goals; it is closed (``server.close()``) a moment later."""
        if self._action_servers.get(server.name) is server:
            del self._action_servers[server.name]
            self._closing[server.name] = server
