"""One small handler per op, ``(session, op) -> None``, registered by op class."""

import asyncio

from protocol import ops

from . import actions, services, topics


def _set_level(session, op) -> None:
    """The protocol session already applied it; nothing else to do."""


def _auth(session, op) -> None:
    session.gateway.policy.authenticate(session, op)


def _ping(session, op) -> None:
    """Answered at once, in order with what is queued for the client: the round trip a page
    sees includes the wait in its outbox, as its data's does."""
    if op.t is not None:
        session.clock.sample(op.t, asyncio.get_running_loop().time())
        session.clock.pinging = True
    pong = {'op': 'pong', 'id': op.id}
    if op.t is not None:
        pong['t'] = op.t
    session.reply(pong)


HANDLERS = {
    ops.Advertise: topics.advertise,
    ops.Unadvertise: topics.unadvertise,
    ops.Publish: topics.publish,
    ops.Subscribe: topics.subscribe,
    ops.Unsubscribe: topics.unsubscribe,
    ops.CallService: services.call_service,
    ops.ServiceResponse: services.service_response,
    ops.AdvertiseService: services.advertise_service,
    ops.UnadvertiseService: services.unadvertise_service,
    ops.SendActionGoal: actions.send_action_goal,
    ops.CancelActionGoal: actions.cancel_action_goal,
    ops.AdvertiseAction: actions.advertise_action,
    ops.UnadvertiseAction: actions.unadvertise_action,
    ops.ActionFeedback: actions.action_feedback,
    ops.ActionResult: actions.action_result,
    ops.SetLevel: _set_level,
    ops.Auth: _auth,
    ops.Ping: _ping,
}
