"""send_action_goal, cancel_action_goal, advertise_action, action_feedback, action_result,
unadvertise_action."""

from __future__ import annotations

from typing import TYPE_CHECKING

import asyncio

from protocol.convert import from_args, from_json
from protocol.errors import ProtocolError
from protocol.msgdefs import normalize
from protocol.ops import (
    ActionFeedback, ActionResult, AdvertiseAction, CancelActionGoal, SendActionGoal, UnadvertiseAction,
)

from ...backends import blame
from ...backends.base import (
    SERVER_WAIT, STATUS_ABORTED, STATUS_CANCELED, STATUS_SUCCEEDED, STATUS_UNKNOWN, ActionServerCallbacks,
)
from .topics import absolute, unadvertised

if TYPE_CHECKING:
    from ..session import ClientSession

TERMINAL = (STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED)
SEND_GOAL = '/_action/send_goal'   # an action server's hidden service (ROS 2's, the sim's too)
HIDDEN_GOALS = 100                 # goals sent through it a client's disconnect cancels, at most


class HiddenGoal:
    """A goal a client sent through an action's hidden ``_action/send_goal`` service: canceled, as
    its ``send_action_goal`` goals are, when the client disconnects (a robot under a program stops
    when the program's connection drops), through the action's ``_action/cancel_goal``."""

    def __init__(self, s: ClientSession, action: str, uuid: bytes):
        self.backend, self.action, self.uuid = s.backend, action, bytes(uuid)
        self.goal_id = f'{action}{SEND_GOAL}:{self.uuid.hex()}'

    async def cancel(self) -> None:
        request = {'goal_info': {'goal_id': {'uuid': self.uuid}, 'stamp': {'sec': 0, 'nanosec': 0}}}
        await self.backend.call_service(f'{self.action}/_action/cancel_goal', 'action_msgs/srv/CancelGoal',
                                        request, SERVER_WAIT)


def sent_through_hidden_service(s: ClientSession, service: str, request: dict, response: dict) -> None:
    """After a call of ``service``: an accepted goal of ``NAME/_action/send_goal`` is kept for the
    client's disconnect (the newest ``HIDDEN_GOALS``; goals that ended need no cancel, and one of
    them costs a cancel answered GOAL_TERMINATED)."""
    if not service.endswith(SEND_GOAL) or response.get('accepted') is not True:
        return
    goal = HiddenGoal(s, service[:-len(SEND_GOAL)], request['goal_id']['uuid'])
    s.client_goals[goal.goal_id] = goal
    hidden = [k for k, g in s.client_goals.items() if isinstance(g, HiddenGoal)]
    for key in hidden[:-HIDDEN_GOALS]:
        del s.client_goals[key]


def send_action_goal(s: ClientSession, op: SendActionGoal) -> None:
    s.spawn(_send_goal(s, op, op.id or s.next_id(f'send_action_goal:{op.action}')), op.OP, op.id)


async def _send_goal(s: ClientSession, op: SendActionGoal, id: str) -> None:
    name = absolute(op.action)
    reply = {'op': 'action_result', 'action': op.action, 'id': id}
    adef = None
    try:
        type = normalize(op.action_type, 'action')
        adef = s.backend.action_def(type)
        goal = from_args(s.backend.defs, adef.goal, op.args)

        def on_feedback(values: dict) -> None:
            s.reply({'op': 'action_feedback', 'action': op.action, 'id': id, 'values': values},
                    op.compression, op.fragment_size, msgdef=adef.feedback, defs=s.backend.defs, body='values')

        handle = await s.backend.send_goal(name, type, goal, on_feedback if op.feedback else None)
        s.client_goals[id] = handle
        try:
            outcome = await handle.result()
        finally:
            s.client_goals.pop(id, None)
    except asyncio.CancelledError:
        raise
    except Exception as e:   # the caller always gets its result; bugs are also logged
        s.reply({**reply, 'values': blame.sentence(e), 'status': STATUS_UNKNOWN, 'result': False})
        if not blame.answerable(e):
            s.report(op.OP, op.id, e)
        return
    s.reply({**reply, 'values': outcome.result, 'status': outcome.status, 'result': True},
            op.compression, op.fragment_size, msgdef=adef.result, defs=s.backend.defs, body='values')


def cancel_action_goal(s: ClientSession, op: CancelActionGoal) -> None:
    handle = s.client_goals.get(op.id)
    if handle is None:
        s.status('warning', f'no running goal with id {op.id} on {op.action}', op.OP, op.id)
        return
    s.spawn(handle.cancel(), op.OP, op.id)


def advertise_action(s: ClientSession, op: AdvertiseAction) -> None:
    name = absolute(op.action)
    type = normalize(op.type, 'action')
    adef = s.backend.action_def(type)
    if name in s.actions:
        _release(s, name)

    def on_goal(goal) -> None:
        s.server_goals[goal.goal_id] = (goal, name, adef)
        # the name and type as the client advertised them: clients match on them (rosbridge echoes them)
        s.reply({'op': 'send_action_goal', 'action': op.action, 'action_type': op.type,
                 'id': goal.goal_id, 'args': goal.request, 'feedback': True})

    def on_cancel(goal) -> None:
        s.reply({'op': 'cancel_action_goal', 'action': op.action, 'id': goal.goal_id})

    handle = s.backend.advertise_action(name, type, ActionServerCallbacks(on_goal, on_cancel))
    s.actions[name] = (handle, adef)


def _goal(s: ClientSession, op, remove: bool):
    entry = (s.server_goals.pop if remove else s.server_goals.get)(op.id, None) if op.id else None
    if entry is None:
        raise ProtocolError(f'no goal with id {op.id} is running on {op.action}', op=op.OP, id=op.id)
    return entry


def action_feedback(s: ClientSession, op: ActionFeedback) -> None:
    goal, _, adef = _goal(s, op, remove=False)
    goal.publish_feedback(from_json(s.backend.defs, adef.feedback, op.values or {}))


def action_result(s: ClientSession, op: ActionResult) -> None:
    goal, _, adef = _goal(s, op, remove=True)
    if op.result is False:
        status, values = op.status if op.status in TERMINAL else STATUS_ABORTED, {}
    else:
        status = op.status if op.status in TERMINAL else STATUS_SUCCEEDED
        values = op.values if isinstance(op.values, dict) else {}
    try:
        result = from_json(s.backend.defs, adef.result, values)
    except ProtocolError:
        goal.finish(STATUS_ABORTED, from_json(s.backend.defs, adef.result, {}))
        raise
    goal.finish(status, result)


def unadvertise_action(s: ClientSession, op: UnadvertiseAction) -> None:
    unadvertised(s, absolute(op.action), s.actions, op, _release)


def _release(s: ClientSession, name: str) -> None:
    handle, _ = s.actions.pop(name)
    for gid, (_, action, _) in list(s.server_goals.items()):
        if action == name:
            del s.server_goals[gid]
    handle.destroy()
