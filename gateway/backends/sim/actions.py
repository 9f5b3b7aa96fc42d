"""Action servers of the sim graph, with the hidden services and topics of a ROS 2 action server.

Every action server NAME of type X (the demo's ``/fibonacci``, turtlesim's ``rotate_absolute``,
actions clients advertise through the gateway) serves ``NAME/_action/send_goal`` (X_SendGoal),
``NAME/_action/get_result`` (X_GetResult) and ``NAME/_action/cancel_goal``
(action_msgs/srv/CancelGoal), and publishes ``NAME/_action/feedback`` (X_FeedbackMessage) and the
latched ``NAME/_action/status`` (action_msgs/msg/GoalStatusArray), as rcl_action does: clients that
use them find them (roslibjs's ``Action.cancelAllGoals()`` calls ``cancel_goal`` with a zero goal
id and stamp, which cancels every goal). Cancel requests are answered as
``rcl_action_process_cancel_request`` answers them. A finished goal is kept for ``get_result`` and
for cancel answers, as rcl keeps it until its result expires (``RESULT_TIMEOUT``, rclpy's default),
and at most ``KEPT`` of them per server: a sim runs for days.
"""

from __future__ import annotations

import asyncio
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..base import (
    CANCEL_ERROR_GOAL_TERMINATED, CANCEL_ERROR_NONE, CANCEL_ERROR_UNKNOWN_GOAL_ID, STATUS_ABORTED,
    STATUS_ACCEPTED, STATUS_CANCELED, STATUS_CANCELING, STATUS_EXECUTING, STATUS_SUCCEEDED,
    STATUS_UNKNOWN, ActionResult, ActionServerCallbacks, QoS,
)

if TYPE_CHECKING:
    from .graph import Node

Message = dict[str, Any]
TERMINAL = (STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED)
CANCELABLE = (STATUS_ACCEPTED, STATUS_EXECUTING)   # rcl_action_goal_handle_is_cancelable
RESULT_TIMEOUT = 900.0   # s a finished goal is kept: rclpy's ActionServer result_timeout
KEPT = 100               # finished goals kept per server at most
STATUS_QOS = QoS(depth=1, transient_local=True)    # rcl_action_qos_profile_status_default
ZERO_ID = bytes(16)


def clock() -> tuple[int, int]:
    """(sec, nanosec) now, on the clock goal stamps and ``rosapi/get_time`` both read."""
    ns = time.time_ns()
    return ns // 1_000_000_000, ns % 1_000_000_000


class SimServerGoal:
    """A goal as the action server sees it."""

    def __init__(self, server: SimActionServer, request: Message, goal_id: bytes | None = None):
        self.server, self.request = server, request
        self.uuid = bytes(goal_id) if goal_id else uuid.uuid4().bytes
        self.goal_id = str(uuid.UUID(bytes=self.uuid))
        self.stamp = clock()
        self.status = STATUS_ACCEPTED
        self.finished_at = 0.0
        self.feedback_listeners: list[Callable[[Message], None]] = []
        self.done: asyncio.Future = asyncio.get_running_loop().create_future()

    @property
    def cancel_requested(self) -> bool:
        return self.status == STATUS_CANCELING

    @property
    def active(self) -> bool:
        return self.status not in TERMINAL

    def info(self) -> Message:
        """Its action_msgs/msg/GoalInfo."""
        return {'goal_id': {'uuid': self.uuid}, 'stamp': {'sec': self.stamp[0], 'nanosec': self.stamp[1]}}

    def publish_feedback(self, feedback: Message) -> None:
        if not self.active:
            return
        if self.status == STATUS_ACCEPTED:
            self.status = STATUS_EXECUTING
            self.server.publish_status()
        for listener in tuple(self.feedback_listeners):
            listener(feedback)
        self.server.publish_feedback(self, feedback)

    def finish(self, status: int, result: Message) -> None:
        if not self.active:
            return
        self.status = status
        self.finished_at = time.monotonic()
        self.server.retire(self)
        if not self.done.done():
            self.done.set_result(ActionResult(status, result))


class SimClientGoal:
    """A goal as the action client sees it."""

    def __init__(self, goal: SimServerGoal):
        self._goal = goal
        self.goal_id = goal.goal_id

    async def result(self) -> ActionResult:
        return await asyncio.shield(self._goal.done)

    async def cancel(self) -> None:
        goal = self._goal
        if goal.status in CANCELABLE:
            goal.server.cancel([goal])


class SimActionServer:
    """An action server with its hidden endpoints (made here, destroyed with it)."""

    def __init__(self, node: Node, name: str, type: str, callbacks: ActionServerCallbacks):
        self.node, self.name, self.type, self.callbacks = node, name, type, callbacks
        self.goals: dict[bytes, SimServerGoal] = {}                   # active, by uuid
        self.finished: OrderedDict[bytes, SimServerGoal] = OrderedDict()   # oldest first
        self._endpoints: list = []
        prefix = f'{name}/_action/'
        try:
            self._feedback = self._own(node.create_publisher(prefix + 'feedback', f'{type}_FeedbackMessage'))
            self._status = self._own(node.create_publisher(
                prefix + 'status', 'action_msgs/msg/GoalStatusArray', STATUS_QOS))
            self._status.retain(self.status_message)   # built when a subscriber joins
            self._own(node.create_service(prefix + 'send_goal', f'{type}_SendGoal', self._send_goal))
            self._own(node.create_service(prefix + 'get_result', f'{type}_GetResult', self._get_result))
            self._own(node.create_service(prefix + 'cancel_goal', 'action_msgs/srv/CancelGoal', self._cancel_goal))
        except Exception:
            self._destroy_endpoints()
            raise

    def _own(self, endpoint):
        """Destroyed by the server (after its goals are aborted), not by its node."""
        self.node._owned.discard(endpoint)
        self._endpoints.append(endpoint)
        return endpoint

    # goals -----------------------------------------------------------------------------------
    def accept(self, request: Message, goal_id: bytes | None = None,
               on_feedback: Callable[[Message], None] | None = None) -> SimServerGoal:
        """A new goal, accepted now and handed to the server's ``on_goal``."""
        goal = SimServerGoal(self, request, goal_id)
        if on_feedback:
            goal.feedback_listeners.append(on_feedback)
        self.goals[goal.uuid] = goal
        self.publish_status()
        self.callbacks.on_goal(goal)
        return goal

    def retire(self, goal: SimServerGoal) -> None:
        """A goal has finished: kept for get_result and cancel answers for a while."""
        self.goals.pop(goal.uuid, None)
        self.finished[goal.uuid] = goal
        self._expire()
        self.publish_status()

    def _expire(self) -> None:
        oldest = time.monotonic() - RESULT_TIMEOUT
        while self.finished and (len(self.finished) > KEPT
                                 or next(iter(self.finished.values())).finished_at < oldest):
            self.finished.popitem(last=False)

    def cancel(self, goals: list[SimServerGoal]) -> None:
        """Goals go to CANCELING; the server's ``on_cancel`` decides when they finish."""
        for goal in goals:
            goal.status = STATUS_CANCELING
        self.publish_status()
        for goal in goals:
            if goal.status == STATUS_CANCELING:   # an on_cancel before may have finished it
                self.callbacks.on_cancel(goal)

    # topics ----------------------------------------------------------------------------------
    def status_message(self) -> Message:
        self._expire()
        goals = [*self.finished.values(), *self.goals.values()]
        return {'status_list': [{'goal_info': g.info(), 'status': g.status} for g in goals]}

    def publish_status(self) -> None:
        if self._endpoints and self._status.subscription_count:
            self._status.publish(self.status_message())
            self._status.retain(self.status_message)

    def publish_feedback(self, goal: SimServerGoal, feedback: Message) -> None:
        if self._endpoints and self._feedback.subscription_count:
            self._feedback.publish({'goal_id': {'uuid': goal.uuid}, 'feedback': feedback})

    # hidden services -------------------------------------------------------------------------
    def _send_goal(self, request: Message) -> Message:
        goal_id = bytes(request['goal_id']['uuid'])
        if goal_id in self.goals or goal_id in self.finished:   # rclpy refuses a goal id it tracks
            return {'accepted': False, 'stamp': {'sec': 0, 'nanosec': 0}}
        goal = self.accept(request['goal'], goal_id)
        return {'accepted': True, 'stamp': goal.info()['stamp']}

    async def _get_result(self, request: Message) -> Message:
        goal_id = bytes(request['goal_id']['uuid'])
        goal = self.goals.get(goal_id) or self.finished.get(goal_id)
        if goal is None:
            return {'status': STATUS_UNKNOWN, 'result': self.node.graph.default_result(self.type)}
        outcome = await asyncio.shield(goal.done)
        return {'status': outcome.status, 'result': outcome.result}

    def _cancel_goal(self, request: Message) -> Message:
        """As ``rcl_action_process_cancel_request``: a goal id alone cancels that goal; a stamp
        alone, every goal accepted at or before it; both zero, every goal; both, the union."""
        info = request['goal_info']
        goal_id = bytes(info['goal_id']['uuid'])
        stamp = info['stamp']['sec'] * 1_000_000_000 + info['stamp']['nanosec']
        if goal_id != ZERO_ID and not stamp:
            goal = self.goals.get(goal_id) or self.finished.get(goal_id)
            if goal is None:
                return {'return_code': CANCEL_ERROR_UNKNOWN_GOAL_ID, 'goals_canceling': []}
            if goal.status not in CANCELABLE:
                return {'return_code': CANCEL_ERROR_GOAL_TERMINATED, 'goals_canceling': []}
            chosen = [goal]
        else:
            before = stamp or float('inf')
            chosen = [g for g in self.goals.values() if g.status in CANCELABLE and (
                g.stamp[0] * 1_000_000_000 + g.stamp[1] <= before or g.uuid == goal_id)]
        self.cancel(chosen)
        return {'return_code': CANCEL_ERROR_NONE, 'goals_canceling': [g.info() for g in chosen]}

    # ------------------------------------------------------------------------------------------
    def _destroy_endpoints(self) -> None:
        endpoints, self._endpoints = self._endpoints, []
        for endpoint in endpoints:
            endpoint.destroy()

    def destroy(self) -> None:
        for goal in list(self.goals.values()):
            goal.finish(STATUS_ABORTED, self.node.graph.default_result(self.type))
        self._destroy_endpoints()
        graph = self.node.graph
        if graph._actions.get(self.name) is self:
            del graph._actions[self.name]
        self.node._owned.discard(self)
