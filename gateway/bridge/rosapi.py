"""The rosapi services, answered by the gateway from the backend's graph.

Both ``/rosapi/topics`` (roslibpy) and ``rosapi/topics`` (roslibjs) reach these. They are
listed in the graph as services of a ``/rosapi`` node, with ``rosapi_msgs/srv/*`` types, as the
reference's rosapi node lists them.

Hidden names (an action's ``/fibonacci/_action/status``, ``_action/cancel_goal``: ``is_hidden``)
are left out of the listings (topics, services, their ``*_for_type``, node_details), as the
reference's rosapi and ROS 2's tools leave them out unless asked (``--include-hidden-topics``);
``action_servers`` lists the actions whose hidden topics are there, as the reference finds them.
A question naming a hidden name (topic_type, service_type, publishers, ...) is answered: naming
it is asking for it, as ``ros2 topic info /fibonacci/_action/status`` answers (the reference's
topic_type and service_type answer '' there).
"""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Any

from protocol.convert import from_args
from protocol.errors import ProtocolError
from protocol.msgdefs import Definitions, MsgDef, normalize

from ..backends.base import BackendError, is_hidden
from ..rules.access import Action

if TYPE_CHECKING:
    from .session import ClientSession

NODE = '/rosapi'
PREFIX = '/rosapi/'
_defs: Definitions | None = None


def defs() -> Definitions:
    global _defs
    if _defs is None:
        _defs = Definitions.jazzy()
    return _defs


def handles(name: str) -> bool:
    return name.startswith(PREFIX) and name[len(PREFIX):] in SERVICES


def listing() -> list[tuple[str, str]]:
    return [(PREFIX + name, f'rosapi_msgs/srv/{type}') for name, (type, _) in sorted(SERVICES.items())]


async def call(s: ClientSession, name: str, args: Any) -> dict:
    short = name[len(PREFIX):]
    type, fn = SERVICES[short]
    srv = defs().srv(f'rosapi_msgs/srv/{type}')
    request = from_args(defs(), srv.request, args)
    result = fn(s, **request)
    if hasattr(result, '__await__'):
        result = await result
    return result


# --- listings ------------------------------------------------------------------------------

def _visible(s: ClientSession, kind: str, pairs):
    return [(n, t) for n, t in pairs if s.listed(kind, n)]


def _topics(s, hidden: bool = False):
    return _visible(s, 'topics', s.backend.topics(hidden))


def _services(s, hidden: bool = False):
    own = [(n, t) for n, (t, _) in s.gateway.own_services.items()]
    return _visible(s, 'services', [*s.backend.services(hidden), *listing(), *own])


def topics(s):
    pairs = _topics(s)
    return {'topics': [n for n, _ in pairs], 'types': [t for _, t in pairs]}


def topics_for_type(s, type):
    full = _full(type, 'msg')
    return {'topics': [n for n, t in _topics(s) if t == full]}


def topics_and_raw_types(s):
    pairs = _topics(s)
    texts = []
    for _, t in pairs:
        try:
            texts.append(s.backend.full_text(s.backend.msg_def(t)))
        except LookupError:
            texts.append('')
    return {'topics': [n for n, _ in pairs], 'types': [t for _, t in pairs], 'typedefs_full_text': texts}


def topic_type(s, topic):
    return {'type': dict(_topics(s, hidden=True)).get(_abs(topic), '')}


def services(s):
    return {'services': [n for n, _ in _services(s)]}


def services_for_type(s, type):
    full = _full(type, 'srv')
    return {'services': [n for n, t in _services(s) if t == full]}


def service_type(s, service):
    return {'type': dict(_services(s, hidden=True)).get(_abs(service), '')}


def service_providers(s, service):
    name = _abs(service)
    if not s.listed('services', name):
        return {'providers': []}
    if handles(name) or name in s.gateway.own_services:
        return {'providers': [NODE if handles(name) else '/' + s.gateway.settings.node_name.strip('/')]}
    return {'providers': s.backend.service_providers(name)}


def service_node(s, service):
    providers = service_providers(s, service)['providers']
    return {'node': providers[0] if providers else ''}


def nodes(s):
    return {'nodes': sorted({*s.backend.nodes(), NODE})}


def node_details(s, node):
    if _abs(node) == NODE:
        return {'subscribing': [], 'publishing': [], 'services': [n for n, _ in listing()]}
    try:
        info = s.backend.node_info(_abs(node))
    except BackendError:
        return {'subscribing': [], 'publishing': [], 'services': []}
    def listed(kind: str, names: list[str]) -> list[str]:
        return [n for n in names if not is_hidden(n) and s.listed(kind, n)]

    return {'subscribing': listed('topics', info.subscribing), 'publishing': listed('topics', info.publishing),
            'services': listed('services', info.services)}


def publishers(s, topic):
    name = _abs(topic)
    return {'publishers': s.backend.publishers(name) if s.listed('topics', name) else []}


def subscribers(s, topic):
    name = _abs(topic)
    return {'subscribers': s.backend.subscribers(name) if s.listed('topics', name) else []}


def action_servers(s):
    return {'action_servers': [n for n, _ in _visible(s, 'actions', s.backend.actions())]}


def action_type(s, action):
    return {'type': dict(_visible(s, 'actions', s.backend.actions())).get(_abs(action), '')}


def interfaces(s):
    return {'interfaces': s.backend.interfaces()}


# --- type details --------------------------------------------------------------------------

def _details(s, msg: MsgDef) -> dict:
    return {'typedefs': s.backend.typedefs(msg)}


def message_details(s, type):
    return _details(s, _lookup(s.backend.msg_def, type))


def service_request_details(s, type):
    return _details(s, _lookup(s.backend.srv_def, type).request)


def service_response_details(s, type):
    return _details(s, _lookup(s.backend.srv_def, type).response)


def action_goal_details(s, type):
    return _details(s, _lookup(s.backend.action_def, type).goal)


def action_result_details(s, type):
    return _details(s, _lookup(s.backend.action_def, type).result)


def action_feedback_details(s, type):
    return _details(s, _lookup(s.backend.action_def, type).feedback)


def _lookup(fn, type):
    try:
        return fn(type)
    except LookupError as e:
        raise BackendError(str(e)) from None


# --- parameters ----------------------------------------------------------------------------

def _param(s, name: str) -> tuple[str, str]:
    node, sep, param = name.partition(':')
    if not sep or not node or not param:
        raise BackendError(f'parameter names are "<node>:<param>", got {name!r}')
    if not s.listed('params', name):
        raise BackendError(f'parameter {name} is not allowed by this gateway')
    return _abs(node), param


async def get_param(s, name, default_value):
    node, param = _param(s, name)
    try:
        return {'value': json.dumps(await s.backend.get_param(node, param))}
    except (KeyError, BackendError):
        return {'value': default_value or 'null'}


async def set_param(s, name, value):
    node, param = _param(s, name)
    s.require(Action.PARAM, name, 'call_service', None)
    try:
        parsed = json.loads(value)
    except ValueError:
        parsed = value   # a bare string, as some clients send
    try:
        await s.backend.set_param(node, param, parsed)
    except (BackendError, KeyError) as e:
        return {'successful': False, 'reason': str(e)}
    return {'successful': True, 'reason': ''}


async def has_param(s, name):
    node, param = _param(s, name)
    try:
        await s.backend.get_param(node, param)
        return {'exists': True}
    except (KeyError, BackendError):
        return {'exists': False}


async def delete_param(s, name):
    node, param = _param(s, name)
    s.require(Action.PARAM, name, 'call_service', None)
    await s.backend.delete_param(node, param)
    return {}


async def get_param_names(s):
    names = await s.backend.param_names()
    return {'names': [n for n in names if s.listed('params', n)]}


def get_time(s):
    sec, nanosec = s.backend.now()
    return {'time': {'sec': sec, 'nanosec': nanosec}}


def get_ros_version(s):
    return {'version': 2, 'distro': os.environ.get('ROS_DISTRO', 'jazzy')}


def _abs(name: str) -> str:
    return name if name.startswith('/') else '/' + name


def _full(type: str, kind: str) -> str:
    try:
        return normalize(type, kind)
    except LookupError as e:
        raise ProtocolError(str(e)) from None


SERVICES = {
    'topics': ('Topics', topics),
    'topics_for_type': ('TopicsForType', topics_for_type),
    'topics_and_raw_types': ('TopicsAndRawTypes', topics_and_raw_types),
    'topic_type': ('TopicType', topic_type),
    'services': ('Services', services),
    'services_for_type': ('ServicesForType', services_for_type),
    'service_type': ('ServiceType', service_type),
    'service_providers': ('ServiceProviders', service_providers),
    'service_node': ('ServiceNode', service_node),
    'nodes': ('Nodes', nodes),
    'node_details': ('NodeDetails', node_details),
    'publishers': ('Publishers', publishers),
    'subscribers': ('Subscribers', subscribers),
    'action_servers': ('GetActionServers', action_servers),
    'action_type': ('ActionType', action_type),
    'interfaces': ('Interfaces', interfaces),
    'message_details': ('MessageDetails', message_details),
    'service_request_details': ('ServiceRequestDetails', service_request_details),
    'service_response_details': ('ServiceResponseDetails', service_response_details),
    'action_goal_details': ('ActionGoalDetails', action_goal_details),
    'action_result_details': ('ActionResultDetails', action_result_details),
    'action_feedback_details': ('ActionFeedbackDetails', action_feedback_details),
    'get_param': ('GetParam', get_param),
    'set_param': ('SetParam', set_param),
    'has_param': ('HasParam', has_param),
    'delete_param': ('DeleteParam', delete_param),
    'get_param_names': ('GetParamNames', get_param_names),
    'get_time': ('GetTime', get_time),
    'get_ros_version': ('GetROSVersion', get_ros_version),
}
