"""The pump: one thread that moves the gateway's topic and service traffic between rcl and the loop.

rclpy's executors pace every message with their own wake-ups. Measured on Fast DDS (PyPI Jazzy
wheels, rclpy 7.1.6, one process, std_msgs/String of 64 B, 32 in flight, a busy and a quiet
2-core machine): ``MultiThreadedExecutor`` 41–2,300 msg/s, ``SingleThreadedExecutor``
3,200–8,900 msg/s, this loop 29,000–76,000 msg/s. ``EventsExecutor`` hung there as soon as
another thread published, and delivered nothing from another process.

So subscriptions, service clients and services served by the gateway are plain rcl entities
(``_rclpy.Subscription`` / ``Client`` / ``Service``) that no executor sees. The pump waits on
them with one rcl wait set, takes everything that is ready, and hands it to the loop in batches:
one ``call_soon_threadsafe`` when the batch goes from empty to non-empty, not one per message.
The loop sends (requests, responses) itself; rcl allows that from any thread. Entities are
destroyed by the pump thread after its wait, so a handle is never destroyed while waited on.

Each batch is delivered inside the gateway's outbox cork, so a client gets its share of a batch
in one socket write. When the gateway publishes, the loop takes from its own readers of that
topic itself (``take_here``): Fast DDS delivers to a process's own readers inside the publish
call, and the message then skips the hop through the pump and back. While the gateway keeps
publishing to a topic, the pump does not wait on its readers (``hold``/``release``).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import threading
from collections.abc import Callable
from typing import Any

log = logging.getLogger('rosgate.rclpy')

BUDGET = 64        # items taken from one entity per round, so one busy topic cannot starve others
BACKLOG = 128      # items waiting for the loop before the pump stops taking (DDS queues the rest)


def _rclpy():
    from rclpy.impl.implementation_singleton import rclpy_implementation  # noqa: PLC0415
    return rclpy_implementation


class Entity:
    """An rcl entity the pump waits on. ``take(push)`` runs on the pump thread and pushes
    ``(fn, arg)`` pairs that the loop runs as ``fn(arg)``."""

    kind = ''

    def __init__(self, handle):
        self.handle = handle

    def take(self, push: Callable[[Callable, Any], None]) -> None:
        raise NotImplementedError


class TopicReader(Entity):
    kind = 'subscription'

    def __init__(self, handle, msg_type, convert: Callable, deliver: Callable, report: Callable,
                 decode: Callable | None = None):
        """decode: CDR bytes -> dict (raising for what it leaves to convert); with it the reader
        takes raw messages, which costs less than rclpy's message objects. Without it the reader
        takes raw messages only while ``keep_cdr`` is set (by the loop: someone wants the CDR as
        received): taking the CDR and deserializing it costs more than taking the message object
        (measured, Fast DDS, one process: a 1 MB PointCloud2 356-380 µs against 197-215 µs; a
        JointState of 12 joints about the same, 22-34 µs)."""
        super().__init__(handle)
        self.msg_type, self._convert, self._deliver, self._report = msg_type, convert, deliver, report
        self._decode = decode
        self.keep_cdr = False

    def _from_cdr(self, data: bytes):
        if self._decode is not None:
            try:
                return self._decode(data)
            except Exception:  # noqa: BLE001 (cdr.Slow, or a malformed message: rclpy decides)
                if getattr(self.msg_type, 'raw_only', False):
                    raise       # a type described by the graph: no class to decode with
        from rclpy.serialization import deserialize_message  # noqa: PLC0415
        return self._convert(deserialize_message(data, self.msg_type))

    def take(self, push) -> int:
        """Pushes ``(deliver, (message dict, CDR bytes as taken or None))``; returns how many
        messages it took (at most BUDGET)."""
        raw = self._decode is not None or self.keep_cdr
        take, msg_type, deliver = self.handle.take_message, self.msg_type, self._deliver
        convert = self._from_cdr if raw else self._convert
        for n in range(BUDGET):
            got = take(msg_type, raw)
            if got is None:
                return n
            try:
                push(deliver, (convert(got[0]), got[0] if raw else None))
            except Exception as e:  # noqa: BLE001 (a message the converter cannot express)
                push(self._report, e)
        return BUDGET


class ServiceCaller(Entity):
    """Responses of one rcl client, matched to the loop's futures by sequence number."""

    kind = 'client'

    def __init__(self, handle, srv_type):
        super().__init__(handle)
        self.srv_type = srv_type
        self.pending: dict[int, Any] = {}     # sequence number -> asyncio.Future (loop only)

    def take(self, push) -> None:
        take, response_type = self.handle.take_response, self.srv_type.Response
        for _ in range(BUDGET):
            header, response = take(response_type)
            if header is None:
                return
            push(self._settle, (header.request_id.sequence_number, response))

    def _settle(self, item) -> None:          # on the loop
        future = self.pending.pop(item[0], None)
        if future is not None and not future.done():
            future.set_result(item[1])


class ServiceServer(Entity):
    """Requests to a service served by the gateway; ``serve((request, header))`` runs on the loop."""

    kind = 'service'

    def __init__(self, handle, srv_type, serve: Callable):
        super().__init__(handle)
        self.srv_type, self._serve = srv_type, serve

    def take(self, push) -> None:
        take, request_type = self.handle.service_take_request, self.srv_type.Request
        for _ in range(BUDGET):
            got = take(request_type)
            if got is None or got[1] is None:
                return
            push(self._serve, got)


class Pump:
    def __init__(self, context, loop, name: str = 'rosgate-pump', scope: Callable = contextlib.nullcontext):
        """scope: a context manager each batch is delivered in (the gateway's outbox cork)."""
        self._context, self._loop, self._scope = context, loop, scope
        self._gc = _rclpy().GuardCondition(context.handle)
        self._lock = threading.Lock()
        self._take_lock = threading.Lock()   # held by whoever takes: pump thread or loop
        self._here = False                    # the loop is inside take_here
        self._entities: list[Entity] = []
        self._held: set[Entity] = set()      # readers the loop takes from itself, for now
        self._doomed: list[Entity] = []
        self._changed = True
        self._stopping = False
        self._batch: collections.deque = collections.deque()
        self._scheduled = False
        self._room = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread (from any thread but the pump's); it destroys every entity."""
        self._stopping = True
        self._room.set()
        self._gc.trigger_guard_condition()
        self._thread.join(timeout=5.0)

    def add(self, entity: Entity) -> None:
        with self._lock:
            self._entities.append(entity)
            self._changed = True
        self._gc.trigger_guard_condition()

    def hold(self, readers: list[TopicReader]) -> None:
        """Stop waiting on these readers until ``release``: the loop takes what they get
        (``take_here``). Otherwise every message the gateway publishes to them wakes the pump."""
        self._hold(self._held.update, readers)

    def release(self, readers: list[TopicReader]) -> None:
        self._hold(self._held.difference_update, readers)

    def _hold(self, change: Callable, readers: list[TopicReader]) -> None:
        with self._lock:
            change(readers)
            self._changed = True
        if self._thread.is_alive():
            self._gc.trigger_guard_condition()

    def remove(self, entity: Entity) -> None:
        """Stop waiting on the entity; the pump destroys its handle."""
        with self._lock:
            self._held.discard(entity)
            if entity in self._entities:
                self._entities.remove(entity)
                self._doomed.append(entity)
            self._changed = True
        if self._thread.is_alive():
            self._gc.trigger_guard_condition()
        else:
            self._destroy_doomed()

    # --- pump thread ------------------------------------------------------------------------

    def _run(self) -> None:
        rclpy = _rclpy()
        wait_set = None
        by_pointer: dict[int, Entity] = {}
        kinds: dict[str, list[Entity]] = {}
        try:
            while not self._stopping:
                if self._changed:
                    with self._lock:
                        self._changed = False
                        entities = [e for e in self._entities if e not in self._held]
                    self._destroy_doomed()
                    kinds = {k: [e for e in entities if e.kind == k]
                             for k in ('subscription', 'client', 'service')}
                    by_pointer = {e.handle.pointer: e for e in entities}
                    wait_set = rclpy.WaitSet(len(kinds['subscription']), 1, 0, len(kinds['client']),
                                             len(kinds['service']), 0, self._context.handle)
                wait_set.clear_entities()
                for e in kinds['subscription']:
                    wait_set.add_subscription(e.handle)
                for e in kinds['client']:
                    wait_set.add_client(e.handle)
                for e in kinds['service']:
                    wait_set.add_service(e.handle)
                wait_set.add_guard_condition(self._gc)
                wait_set.wait(-1)
                if self._stopping:
                    break
                ready = [*wait_set.get_ready_entities('subscription'),
                         *wait_set.get_ready_entities('client'),
                         *wait_set.get_ready_entities('service')]
                with self._take_lock:
                    for pointer in ready:
                        entity = by_pointer.get(pointer)
                        if entity is not None:
                            try:
                                entity.take(self._push)
                            except Exception as e:  # noqa: BLE001 (the entity was destroyed meanwhile)
                                log.debug('taking from %s: %s', entity, e)
                if len(self._batch) > BACKLOG:
                    self._room.clear()
                    if len(self._batch) > BACKLOG:
                        self._room.wait()
        except Exception:  # the context was shut down under the pump
            log.debug('pump stopped', exc_info=True)
        finally:
            with self._lock:
                self._doomed.extend(self._entities)
                self._entities.clear()
            self._destroy_doomed()

    def _destroy_doomed(self) -> None:
        with self._lock:
            doomed, self._doomed = self._doomed, []
        for entity in doomed:
            try:
                entity.handle.destroy_when_not_in_use()
            except Exception as e:  # noqa: BLE001
                log.debug('destroying %s: %s', entity, e)

    def _push(self, fn: Callable, arg) -> None:
        self._batch.append((fn, arg))
        if not self._scheduled:
            self._scheduled = True
            try:
                self._loop.call_soon_threadsafe(self._drain)
            except RuntimeError:
                self._batch.clear()     # the loop is closed: the gateway is gone

    # --- loop ---------------------------------------------------------------------------------

    def take_here(self, readers: list[TopicReader]) -> int | None:
        """Take and deliver on the loop, now, all these readers hold: called after the gateway
        published to their topic. A middleware that delivers to a process's own readers inside
        the publish call (Fast DDS does) then costs no hop through the pump thread and back.
        Messages stay in order: whatever the pump took before is delivered first, and the two
        never take at once. Returns how many messages were delivered (the pump's pending ones
        included), or None when called from inside a delivery (the caller takes later)."""
        if self._here:
            return None
        with self._take_lock:
            self._here = True
            try:
                count = self._drain()
                with self._scope():
                    for reader in readers:
                        try:
                            while (n := reader.take(self._call)) == BUDGET:
                                count += n
                            count += n
                        except Exception as e:  # noqa: BLE001 (the reader was destroyed meanwhile)
                            log.debug('taking from %s: %s', reader, e)
            finally:
                self._here = False
        return count

    @staticmethod
    def _call(fn: Callable, arg) -> None:
        try:
            fn(arg)
        except Exception:
            log.exception('delivering %s', getattr(fn, '__qualname__', fn))

    def _drain(self) -> int:
        self._scheduled = False
        batch = self._batch
        count = len(batch)
        with self._scope():
            while batch:
                self._call(*batch.popleft())
        if not self._room.is_set():   # (the pump clears it, then looks at the batch again)
            self._room.set()
        return count
