"""rclpy.action.server for Python in the IDE page: an ``advertise_action`` on the page's
connection; the goals the gateway forwards (``send_action_goal``) wait for the executor, run
their execute callback as a task, and go back as ``action_feedback`` and ``action_result``.
A cancel the gateway forwards sets the goal's is_cancel_requested when cancel_callback accepts."""

import inspect
from collections import deque
from enum import Enum

from rclpy import _engine

STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING = 1, 2, 3
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6


class GoalResponse(Enum):
    REJECT = 1
    ACCEPT = 2


class CancelResponse(Enum):
    REJECT = 1
    ACCEPT = 2


class ServerGoalHandle:
    def __init__(self, action_server, goal_id, request, op_id):
        self._action_server = action_server
        self._goal_id = goal_id
        self._goal_request = request
        self._op_id = op_id
        self._status = STATUS_ACCEPTED
        self._cancel_requested = False

    def __eq__(self, other):
        return isinstance(other, ServerGoalHandle) and self._op_id == other._op_id

    def __hash__(self):
        return hash(self._op_id)

    @property
    def request(self):
        return self._goal_request

    @property
    def goal_id(self):
        return self._goal_id

    @property
    def is_active(self):
        return self._status in (STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING)

    @property
    def is_cancel_requested(self):
        return self._status == STATUS_CANCELING

    @property
    def status(self):
        return self._status

    def execute(self, execute_callback=None):
        if self.is_active:
            self._status = STATUS_EXECUTING
            self._action_server._execute(self, execute_callback or self._action_server._execute_callback)

    def publish_feedback(self, feedback):
        server = self._action_server
        if hasattr(feedback, "feedback") and not isinstance(feedback, server._action_type.Feedback):
            feedback = feedback.feedback       # a FeedbackMessage
        if not isinstance(feedback, server._action_type.Feedback):
            raise TypeError("Expected type {} or {}, but got {}".format(
                server._action_type.Feedback, server._action_type.Impl.FeedbackMessage, type(feedback)))
        if not self.is_active:
            return
        engine = _engine.engine()
        engine.send({"op": "action_feedback", "action": server._name, "id": self._op_id,
                     "values": engine.to_json(feedback)})

    def succeed(self):
        self._status = STATUS_SUCCEEDED

    def abort(self):
        self._status = STATUS_ABORTED

    def canceled(self):
        self._status = STATUS_CANCELED

    def destroy(self):
        pass


def default_goal_callback(goal_request):
    return GoalResponse.ACCEPT


def default_handle_accepted_callback(goal_handle):
    goal_handle.execute()


def default_cancel_callback(cancel_request):
    return CancelResponse.REJECT


class ActionServer:
    def __init__(self, node, action_type, action_name, execute_callback, *, callback_group=None,
                 goal_callback=default_goal_callback, handle_accepted_callback=default_handle_accepted_callback,
                 cancel_callback=default_cancel_callback, goal_service_qos_profile=None,
                 result_service_qos_profile=None, cancel_service_qos_profile=None, feedback_pub_qos_profile=None,
                 status_pub_qos_profile=None, result_timeout=900):
        self._node = node
        self._action_type = action_type
        self._type = _engine.Engine.type_name(action_type)
        self._name = node.resolve_name(action_name)
        self._execute_callback = execute_callback
        self._goal_callback = goal_callback
        self._handle_accepted_callback = handle_accepted_callback
        self._cancel_callback = cancel_callback
        self.callback_group = callback_group or node.default_callback_group
        self._queue = deque()
        self._goals = {}               # op id -> ServerGoalHandle
        engine = _engine.engine()
        engine.action_servers[self._name] = self
        node._action_servers.append(self)
        engine.send({"op": "advertise_action", "id": engine.next_id("advertise_action", self._name),
                     "action": self._name, "type": self._type})

    def register_execute_callback(self, execute_callback):
        self._execute_callback = execute_callback

    def register_goal_callback(self, goal_callback):
        self._goal_callback = goal_callback

    def register_cancel_callback(self, cancel_callback):
        self._cancel_callback = cancel_callback

    def register_handle_accepted_callback(self, handle_accepted_callback):
        self._handle_accepted_callback = handle_accepted_callback

    def _receive(self, message):
        self._queue.append(message)

    def _has_work(self):
        return bool(self._queue)

    def _take(self):
        m = self._queue.popleft()
        if m.get("op") == "cancel_action_goal":
            return lambda: self._cancel(m)
        return lambda: self._goal(m)

    def _goal(self, m):
        engine = _engine.engine()
        from unique_identifier_msgs.msg import UUID
        request = engine.from_json(self._action_type.Goal, m.get("args") or {})
        response = self._goal_callback(request)
        if response != GoalResponse.ACCEPT:
            self._finish_op(m.get("id"), STATUS_ABORTED, None, refused=True)
            return
        handle = ServerGoalHandle(self, UUID(), request, m.get("id"))
        self._goals[handle._op_id] = handle
        self._handle_accepted_callback(handle)

    def _cancel(self, m):
        handle = self._goals.get(m.get("id"))
        if handle is None or not handle.is_active:
            return
        if self._cancel_callback(handle) == CancelResponse.ACCEPT:
            handle._status = STATUS_CANCELING

    def _execute(self, handle, execute_callback):
        self._node.executor.create_task(self._run, handle, execute_callback)

    async def _run(self, handle, execute_callback):
        result = None
        try:
            result = execute_callback(handle)
            if inspect.iscoroutine(result):
                result = await result
        except BaseException:
            handle._status = STATUS_ABORTED
            self._finish(handle, None)
            raise
        if handle.is_active:
            self._node.get_logger().warning(
                "Goal state not set, assuming aborted. Goal ID: {0}".format(list(getattr(handle.goal_id, "uuid", []))))
            handle._status = STATUS_ABORTED
        self._finish(handle, result)

    def _finish(self, handle, result):
        self._goals.pop(handle._op_id, None)
        self._finish_op(handle._op_id, handle.status, result)

    def _finish_op(self, op_id, status, result, refused=False):
        engine = _engine.engine()
        if result is not None and not isinstance(result, self._action_type.Result):
            raise TypeError("the execute callback returned {!r}, not a {}".format(
                type(result).__name__, self._action_type.Result.__name__))
        values = engine.to_json(result) if result is not None else {}
        engine.send({"op": "action_result", "action": self._name, "id": op_id, "values": values,
                     "status": status, "result": not refused})

    def destroy(self):
        engine = _engine.engine()
        if engine.action_servers.get(self._name) is self:
            del engine.action_servers[self._name]
            engine.send({"op": "unadvertise_action", "action": self._name})
        if self in self._node._action_servers:
            self._node._action_servers.remove(self)
