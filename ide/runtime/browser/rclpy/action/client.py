"""rclpy.action.client for Python in the IDE page: a goal is a ``send_action_goal`` op on the
page's connection (with feedback), its ``action_feedback`` and ``action_result`` answer it.

rosbridge says nothing when a server accepts a goal: the goal counts as accepted at its first
feedback or at its result, and as rejected when the gateway answers with a failure before either
(no server, or the server refused it)."""

import time
import uuid

from rclpy import _engine
from rclpy.task import Future

STATUS_UNKNOWN, STATUS_ACCEPTED, STATUS_EXECUTING, STATUS_CANCELING = 0, 1, 2, 3
STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 4, 5, 6


class ClientGoalHandle:
    def __init__(self, action_client, goal_id, goal_response):
        self._action_client = action_client
        self._goal_id = goal_id
        self._accepted = goal_response
        self._status = STATUS_ACCEPTED if goal_response else STATUS_UNKNOWN
        self._result_future = Future(executor=getattr(action_client._node, "executor", None))
        self._op_id = None

    def __repr__(self):
        return "ClientGoalHandle <id={0}, accepted={1}, status={2}>".format(self.goal_id, self.accepted, self.status)

    @property
    def goal_id(self):
        return self._goal_id

    @property
    def stamp(self):
        return None

    @property
    def accepted(self):
        return self._accepted

    @property
    def status(self):
        return self._status

    def cancel_goal_async(self):
        future = Future(executor=getattr(self._action_client._node, "executor", None))
        self._action_client._cancel(self)
        future.set_result(_CancelResponse(self))
        return future

    def get_result_async(self):
        return self._result_future


class _CancelResponse:
    """action_msgs/srv/CancelGoal's response as far as the page knows it: the cancel was sent."""

    ERROR_NONE = 0

    def __init__(self, handle):
        self.return_code = 0
        self.goals_canceling = [handle.goal_id]


class ActionClient:
    def __init__(self, node, action_type, action_name, *, callback_group=None, goal_service_qos_profile=None,
                 result_service_qos_profile=None, cancel_service_qos_profile=None,
                 feedback_sub_qos_profile=None, status_sub_qos_profile=None):
        self._node = node
        self._action_type = action_type
        self._type = _engine.Engine.type_name(action_type)
        self._action_name = node.resolve_name(action_name) if hasattr(node, "resolve_name") else action_name
        self.callback_group = callback_group or node.default_callback_group
        self._goals = {}               # op id -> ClientGoalHandle
        node._action_clients.append(self)

    def send_goal_async(self, goal, feedback_callback=None, goal_uuid=None):
        if not isinstance(goal, self._action_type.Goal):
            raise TypeError("Expected {}, got {}".format(self._action_type.Goal, type(goal)))
        engine = _engine.engine()
        op_id = engine.next_id("send_action_goal", self._action_name)
        executor = getattr(self._node, "executor", None)
        goal_future = Future(executor=executor)
        goal_id = _uuid_msg(goal_uuid)
        state = {"handle": None}
        impl = self._action_type.Impl

        def accept(accepted):
            if state["handle"] is None:
                state["handle"] = ClientGoalHandle(self, goal_id, accepted)
                state["handle"]._op_id = op_id
                self._goals[op_id] = state["handle"]
                goal_future.set_result(state["handle"])
            return state["handle"]

        def answered(m):
            op = m.get("op")
            if op == "status" and m.get("level") != "error":
                return
            if op == "action_feedback":
                handle = accept(True)
                handle._status = STATUS_EXECUTING
                if feedback_callback is not None:
                    feedback = engine.from_json(self._action_type.Feedback, m.get("values") or {})
                    message = impl.FeedbackMessage(goal_id=goal_id, feedback=feedback)
                    if executor is not None:
                        executor.create_task(feedback_callback, message)
                    else:
                        feedback_callback(message)
                return
            engine.replies.pop(op_id, None)
            self._goals.pop(op_id, None)
            status = m.get("status") if op == "action_result" else STATUS_UNKNOWN
            if op == "status" or (m.get("result") is False and status in (None, STATUS_UNKNOWN)):
                accept(False)                   # refused, or never reached a server
                return
            handle = accept(True)
            handle._status = status if status is not None else STATUS_SUCCEEDED
            values = m.get("values") if isinstance(m.get("values"), dict) else {}
            result = engine.from_json(self._action_type.Result, values)
            handle._result_future.set_result(impl.GetResultService.Response(status=handle._status, result=result))
        engine.replies[op_id] = answered
        engine.send({"op": "send_action_goal", "id": op_id, "action": self._action_name, "action_type": self._type,
                     "args": engine.to_json(goal), "feedback": True})
        return goal_future

    def send_goal(self, goal, feedback_callback=None, goal_uuid=None):
        """Blocks until the goal's result (the program's messages come in meanwhile)."""
        future = self.send_goal_async(goal, feedback_callback, goal_uuid)
        while not future.done():
            _engine.pump(None)
        handle = future.result()
        if not handle.accepted:
            return None
        result = handle.get_result_async()
        while not result.done():
            _engine.pump(None)
        return result.result()

    def _cancel(self, handle):
        if handle._op_id is not None:
            handle._status = STATUS_CANCELING
            _engine.engine().send({"op": "cancel_action_goal", "id": handle._op_id, "action": self._action_name})

    def _cancel_goal_async(self, goal_handle):
        return goal_handle.cancel_goal_async()

    def server_is_ready(self):
        try:
            names = _engine.Engine.rosapi("action_servers").get("action_servers") or []
        except (LookupError, TimeoutError):
            return False
        return self._action_name in names

    def wait_for_server(self, timeout_sec=None):
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.server_is_ready():
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                return False
            time.sleep(0.1 if left is None else min(0.1, left))
        return True

    def destroy(self):
        engine = _engine.engine()
        for op_id, handle in list(self._goals.items()):
            engine.replies.pop(op_id, None)
        self._goals.clear()
        if self in self._node._action_clients:
            self._node._action_clients.remove(self)


def _uuid_msg(goal_uuid):
    from unique_identifier_msgs.msg import UUID
    if goal_uuid is not None:
        return goal_uuid
    return UUID(uuid=list(uuid.uuid4().bytes))
