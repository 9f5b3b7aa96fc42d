"""Actions over rclpy: goals sent to ROS action servers, and action servers served by the gateway.

Runs on two threads: rclpy callbacks on the executor's threads, the gateway's callbacks on the
IOLoop. Every hop to the loop goes through ``backend.hop``; the executor side waits for the loop
with ``Pending`` (an awaitable that yields inside the executor's coroutine task until a
``concurrent.futures.Future`` is done; the loop wakes the executor when it is).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import uuid
from typing import TYPE_CHECKING

from ..base import (
    STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, ActionResult, ActionServerCallbacks,
    BackendError, Message,
)

if TYPE_CHECKING:
    from .backend import RclpyBackend

log = logging.getLogger('rosgate.rclpy')


class Pending:
    """``await Pending(f)`` inside an rclpy executor task: yields until ``f`` is done."""

    __slots__ = ('future',)

    def __init__(self, future: concurrent.futures.Future):
        self.future = future

    def __await__(self):
        while not self.future.done():
            yield
        return self.future


def goal_uuid(goal_id) -> str:
    return str(uuid.UUID(bytes=bytes(goal_id.uuid)))


class RclpyClientGoal:
    """A goal this gateway sent to a ROS action server."""

    def __init__(self, backend: RclpyBackend, handle):
        self._backend, self._handle = backend, handle
        self.goal_id = goal_uuid(handle.goal_id)
        self._result = backend.wrap(handle.get_result_async())

    async def result(self) -> ActionResult:
        response = await asyncio.shield(self._result)
        return ActionResult(response.status, self._backend.convert.to_dict(response.result))

    async def cancel(self) -> None:
        await self._backend.wrap(self._handle.cancel_goal_async())


async def send_goal(backend: RclpyBackend, name: str, client, action_cls, goal: Message, on_feedback,
                    timeout: float) -> RclpyClientGoal:
    convert = backend.convert

    def feedback_cb(message) -> None:   # executor thread
        try:
            backend.hop(on_feedback, convert.to_dict(message.feedback))
        except Exception as e:  # noqa: BLE001
            backend.hop(backend.report, f'feedback of {name}', e)

    future = client.send_goal_async(convert.from_dict(action_cls.Goal, goal),
                                    feedback_callback=feedback_cb if on_feedback else None)
    try:
        handle = await asyncio.wait_for(backend.wrap(future), timeout)
    except asyncio.TimeoutError:
        raise BackendError(f'action server {name} did not answer the goal '
                           f'within {timeout} s') from None
    if not handle.accepted:
        raise BackendError(f'action server {name} rejected the goal')
    return RclpyClientGoal(backend, handle)


class RclpyServerGoal:
    """A goal a ROS action client sent to an action served through the gateway."""

    def __init__(self, server: RclpyActionServer, handle, request: Message):
        self._server, self._handle = server, handle
        self.goal_id = goal_uuid(handle.goal_id)
        self.request = request
        self.done: concurrent.futures.Future = concurrent.futures.Future()
        self.cancel_relayed = False

    def publish_feedback(self, feedback: Message) -> None:
        if not self.done.done():
            server = self._server
            self._handle.publish_feedback(server.backend.convert.from_dict(server.cls.Feedback, feedback))

    def finish(self, status: int, result: Message) -> None:
        if not self.done.done():
            self.done.set_result((status, result))
            self._server.backend.wake()


class RclpyActionServer:
    """rclpy.action.ActionServer whose goals are handed to ActionServerCallbacks on the loop."""

    def __init__(self, backend: RclpyBackend, name: str, type: str, cls, callbacks: ActionServerCallbacks):
        from rclpy.action import ActionServer  # noqa: PLC0415

        self.backend, self.name, self.type, self.cls, self.callbacks = backend, name, type, cls, callbacks
        self.goals: dict[str, RclpyServerGoal] = {}
        self.closed = False
        self._server = ActionServer(
            backend.node, cls, name, self._execute, callback_group=backend.reentrant,
            goal_callback=self._on_goal_request, handle_accepted_callback=self._on_accepted,
            cancel_callback=self._on_cancel_request)

    # executor threads ------------------------------------------------------------------------
    def _on_goal_request(self, request):
        from rclpy.action import GoalResponse  # noqa: PLC0415
        return GoalResponse.REJECT if self.closed else GoalResponse.ACCEPT

    def _on_accepted(self, handle) -> None:
        goal = RclpyServerGoal(self, handle, self.backend.convert.to_dict(handle.request))
        self.goals[goal.goal_id] = goal
        self.backend.hop(self._start, goal)
        handle.execute()

    def _on_cancel_request(self, handle):
        from rclpy.action import CancelResponse  # noqa: PLC0415
        goal = self.goals.get(goal_uuid(handle.goal_id))
        if goal is not None:
            if goal.done.done():
                return CancelResponse.REJECT
            self.backend.hop(self._relay_cancel, goal)
        return CancelResponse.ACCEPT          # a goal not yet started relays it in _start

    async def _execute(self, handle):
        goal = self.goals.get(goal_uuid(handle.goal_id))
        status, result = STATUS_ABORTED, None
        if goal is not None:
            done = await Pending(goal.done)
            if not done.cancelled():
                status, result = done.result()
            self.goals.pop(goal.goal_id, None)
        try:
            if status == STATUS_SUCCEEDED:
                handle.succeed()
            elif status == STATUS_CANCELED and handle.is_cancel_requested:
                handle.canceled()
            else:
                handle.abort()
        except Exception:  # noqa: BLE001 (goal already terminal or server destroyed: rclpy aborts)
            pass
        try:
            return self.backend.convert.from_dict(self.cls.Result, result or {})
        except Exception as e:  # noqa: BLE001
            self.backend.hop(self.backend.report, f'action {self.name}: bad result', e)
            return self.cls.Result()

    # loop ------------------------------------------------------------------------------------
    def _start(self, goal: RclpyServerGoal) -> None:
        if self.closed:
            goal.finish(STATUS_ABORTED, {})
            return
        self.callbacks.on_goal(goal)
        if goal._handle.is_cancel_requested:
            self._relay_cancel(goal)

    def _relay_cancel(self, goal: RclpyServerGoal) -> None:
        if not goal.cancel_relayed and not goal.done.done():
            goal.cancel_relayed = True
            self.callbacks.on_cancel(goal)

    def destroy(self) -> None:
        if self.closed:
            return
        self.closed = True
        goals = list(self.goals.values())
        for goal in goals:
            goal.finish(STATUS_ABORTED, {})
        self.backend.forget_action_server(self)
        if goals:   # let the aborted results reach their clients before the server goes
            self.backend.loop.call_later(1.0, self.close)
        else:
            self.close()

    def close(self) -> None:
        """Destroy the rclpy action server (once)."""
        server, self._server = self._server, None
        if self.backend._closing.get(self.name) is self:
            del self.backend._closing[self.name]
        if server is not None:
            self.backend.destroy_quietly(lambda s: s.destroy(), server)
