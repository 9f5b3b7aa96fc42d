"""rclpy.action for Python in the IDE page."""

from rclpy.action.client import ActionClient, ClientGoalHandle  # noqa: F401
from rclpy.action.server import (ActionServer, CancelResponse, GoalResponse,  # noqa: F401
                                 ServerGoalHandle)


def get_action_names_and_types(node):
    from rclpy import _engine
    names = _engine.Engine.rosapi("action_servers").get("action_servers") or []
    out = []
    for name in names:
        try:
            out.append((name, [_engine.Engine.rosapi("action_type", {"action": name}).get("type", "")]))
        except LookupError:
            out.append((name, []))
    return out
