"""One connected client: its protocol state, outbox, and every ROS entity it created."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
from collections.abc import Callable, Coroutine
from typing import TYPE_CHECKING, Any

from protocol import ops
from protocol.errors import ProtocolError
from protocol.session import Session

from ..backends import blame
from . import encode
from .capabilities import HANDLERS
from ..backends.base import BackendError
from .outbox import Outbox
from ..rules.freshness import ClientClock, Fence
from ..rules.access import Action, Name
from ..rules.names import Refused
from ..rules.settle import Wait

if TYPE_CHECKING:
    from .gateway import Gateway

log = logging.getLogger('rosgate')
_session_ids = itertools.count(1)


class ClientSession:
    def __init__(self, gateway: Gateway, send: Callable[[bytes, bool], Any],
                 send_many: Callable[[list[tuple[bytes, bool]]], Any],
                 close: Callable[[int, str], None], remote: str = '',
                 ping: Callable[[bytes], Any] | None = None):
        settings = gateway.settings
        self.id = next(_session_ids)
        self.gateway, self.backend, self.remote = gateway, gateway.backend, remote
        self.proto = Session(fragment_timeout=settings.fragment_timeout,
                             max_message_size=settings.max_message_size)
        self.outbox = Outbox(send, send_many, byte_limit=settings.send_buffer_limit,
                             on_overflow=self._overflow, on_reply_overflow=self._reply_overflow)
        self._close_connection = close
        self.subscriptions: dict[str, Any] = {}        # topic -> fanout.Subscriber
        self.publishers: dict[str, Any] = {}           # topic -> core.SharedPublisher
        self.services: dict[str, Any] = {}             # service -> (handle, SrvDef)
        self.service_requests: dict[str, tuple[asyncio.Future, Any]] = {}
        self.actions: dict[str, Any] = {}              # action -> (handle, ActionDef)
        self.server_goals: dict[str, Any] = {}         # goal id -> (ServerGoal, action)
        self.client_goals: dict[str, Any] = {}         # send_action_goal id -> ClientGoal
        self.tasks: set[asyncio.Task] = set()
        self.attrs: dict[str, Any] = {}                # role, lease, ... for policy hooks
        self.clock = ClientClock()                     # the client's clock, from its stamped ops
        self.fence = Fence(ping)                       # after a stop, moving commands wait for a pong
        self.closed = False
        self.closing = False   # the server is closing the connection: later ops are not handled
        self.connected_at = gateway.backend.now()
        self._counter = itertools.count(1)

    def open(self) -> None:
        self.outbox.start()
        self.gateway.add(self)

    def next_id(self, prefix: str) -> str:
        return f'{prefix}:{next(self._counter)}'

    # --- incoming ----------------------------------------------------------------------------

    def receive(self, data: str | bytes, text: bool | None = None) -> None:
        """One frame: a text frame as str (or as bytes with text=True: UTF-8 already checked),
        a binary (CBOR) frame as bytes."""
        if self.closed or self.closing:
            return
        now = asyncio.get_running_loop().time()
        self.clock.heard(now)
        if text is None:
            text = not isinstance(data, bytes)
        self.proto.fragments_allowed = self.gateway.policy.signed_in(self)
        try:
            if text:
                items = self.proto.receive_text(data, now)
            else:
                items = self.proto.receive_bytes(data, now)
        except Exception as e:   # a bug in decoding: the frame is lost, the connection is not
            self.report(None, None, e)
            return
        for item in items:
            if isinstance(item, ProtocolError):
                self.report(item.op, item.id, item)
                if item.close is not None:   # past a bound: told why, then disconnected
                    self.closing = True   # later frames, already read, are not handled
                    asyncio.ensure_future(self.hang_up(item.close, f'{item.op or "message"}: past a limit'))
                    return
                continue
            self._take_op(item)

    def _take_op(self, item, why: str | None = None) -> None:
        """One op: admitted by the policy (or waiting with a free lease being settled, then asked
        again), the guards, its handler."""
        handler = HANDLERS.get(type(item))
        if handler is None or self.closed:
            return
        try:
            if why is not None:
                raise ProtocolError(why)
            verdict = self.gateway.policy.admit(self, item)
            if verdict is False:
                return
            if isinstance(verdict, Wait):   # a call on a free lease of a fleet: PostgreSQL's word first
                verdict.then(lambda why: self._take_op(item, why))
                return
            for guard in self.gateway.guards:   # e.g. a run's output for its starter alone
                guard(self, item)
            handler(self, item)
        except Refused as e:   # the rules refused it: a call or goal also gets its failed reply, first
            self.failed(item, e.message)
            self.report(item.OP, item.id, e)
        except Exception as e:  # the one catch site: every failure becomes a status
            self.report(item.OP, item.id, e)

    def failed(self, op, message: str) -> None:
        """The failed reply of a refused call or goal, so clients waiting on it (roslibjs,
        roslibpy) fail at once instead of timing out; other ops have none."""
        if isinstance(op, ops.CallService):
            self.reply({'op': 'service_response', 'service': op.service, 'id': op.id,
                        'values': message, 'result': False})
        elif isinstance(op, ops.SendActionGoal):
            self.reply({'op': 'action_result', 'action': op.action, 'id': op.id,
                        'values': message, 'status': 0, 'result': False})

    def decide(self, action: Action, resource):
        """The one access decision (``rules.access``) about this client: None, or an ``Unauthorized``."""
        return self.gateway.policy.access.decide(self, action, resource)

    def require(self, action: Action, name: str, op: str | None, id: str | None) -> None:
        """``decide`` about a name; a refusal raises as a status naming op and id."""
        why = self.decide(action, Name(name))
        if why is not None:
            raise ProtocolError(why.message, op=op, id=id)

    def listed(self, kind: str, name: str) -> bool:
        """Whether a listing shows this client ``name`` (kind: topics, services, actions, params)."""
        return self.decide(Action.LIST, Name(name, kind)) is None

    def spawn(self, coro: Coroutine, op: str, id: str | None) -> asyncio.Task:
        """Run long work (calls, goals) without blocking this client's later ops."""
        task = asyncio.ensure_future(coro)
        self.tasks.add(task)

        def done(t: asyncio.Task) -> None:
            self.tasks.discard(t)
            if not t.cancelled() and t.exception() is not None:
                self.report(op, id, t.exception())

        task.add_done_callback(done)
        return task

    # --- outgoing ----------------------------------------------------------------------------

    def reply(self, op: dict, compression: str = 'none', fragment_size: int | None = None, **kw) -> None:
        if self.closed:
            return
        if 'id' in op and op['id'] is None:   # an op sent without an id: its reply has none either
            op = {k: v for k, v in op.items() if k != 'id'}
        for payload, binary in encode.frames(op, compression, fragment_size, **kw):
            self.outbox.reply(payload, binary)

    def status(self, level: str, msg: str, op: str | None = None, id: str | None = None) -> None:
        text = msg
        if op:
            text = f'{op}{f" (id {id})" if id else ""}: {msg}'
        status = self.proto.status(level, text, id=id, op=op)
        if status is not None:
            self.reply(status)

    def report(self, op: str | None, id: str | None, exc: BaseException) -> None:
        """The status for a failed op; errors that are nobody's but ours are logged (blame.py)."""
        message = blame.sentence(exc)
        if not blame.answerable(exc):
            log.error('internal error handling %s (id %s)', op, id, exc_info=exc)
        elif op and message.startswith(f'{op}:'):
            message = message[len(op) + 1:].lstrip()
        self.status(getattr(exc, 'level', 'error'), message, op, id)

    def _overflow(self, dropped: int) -> None:
        status = self.proto.status(
            'warning', f'client is not reading fast enough: dropped {dropped} topic messages '
                       f'(send buffer over {self.outbox.byte_limit} bytes)')
        if status is not None:
            self.outbox.reply(encode.text(status))

    def _reply_overflow(self, count: int, size: int) -> None:
        log.warning('client %s (%s) does not read its replies: %d (%d bytes) waiting; closing',
                    self.id, self.remote, count, size)
        self.close_connection(1008, f'not reading replies: {count} replies, {size} bytes waiting')

    def close_connection(self, code: int, reason: str) -> None:
        self.closing = True
        self._close_connection(code, reason)

    async def hang_up(self, code: int, reason: str, flush: float = 1.0) -> None:
        """Close after what is queued for the client went out (at most ``flush`` s); from now
        on its frames are not handled."""
        self.closing = True
        if not self.closed:   # the outbox's pump is writing what came before
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self.outbox.idle.wait(), flush)
        if not self.closed:
            self.close_connection(code, reason)

    # --- teardown ----------------------------------------------------------------------------

    def close(self) -> None:
        """Release every entity this client created (the connection is gone)."""
        if self.closed:
            return
        self.closed = True
        gateway = self.gateway
        gateway.left(self)
        for task in list(self.tasks):
            task.cancel()
        for goal in list(self.client_goals.values()):
            asyncio.ensure_future(_quiet(goal.cancel()))
        self.client_goals.clear()
        for topic in list(self.subscriptions):
            fan = gateway.fanouts.get(topic)
            if fan is not None:
                fan.remove(self, None)
        self.subscriptions.clear()
        for pub in self.publishers.values():
            pub.detach(self.id)
        self.publishers.clear()
        for fut, _ in self.service_requests.values():
            if not fut.done():
                fut.set_exception(BackendError('the client serving this service disconnected'))
        self.service_requests.clear()
        for name, (handle, _) in self.services.items():
            if gateway.service_owners.get(name) is self:
                del gateway.service_owners[name]
            handle.destroy()
        self.services.clear()
        for handle, _ in self.actions.values():
            handle.destroy()   # aborts goals still running
        self.actions.clear()
        self.server_goals.clear()
        self.outbox.close()
        gateway.remove(self)


async def _quiet(coro) -> None:
    try:
        await coro
    except Exception:
        pass
