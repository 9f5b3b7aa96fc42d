"""One small handler per op, ``(session, op) -> None``, registered by op class."""

from protocol import ops

from . import actions, services, topics


def _set_level(session, op) -> None:
    """The protocol session already applied it; nothing else to do."""


def _auth(session, op) -> None:
    session.gateway.policy.authenticate(session, op)


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
}
