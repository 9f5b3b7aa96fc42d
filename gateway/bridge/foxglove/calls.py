"""Foxglove's service calls, parameters and connection graph.

A service call passes the policy as a rosbridge ``call_service`` of the same service (role, names,
the driver lease for command services, the cap on pending calls), runs as one of the session's
tasks (cancelled when it leaves) and is answered with the response's CDR, or a
``serviceCallFailure`` naming why. The gateway's own services (a station's claim) answer knowing
who calls, as for rosbridge clients.

Parameters are named ``/node.param`` and follow the rules of rosapi's: reading them is a read (any
signed-in role), each name must pass the ``--params-glob`` globs, and setting or removing one
needs the ``param`` permission (an admin; anyone with --auth off). The connection graph is a read
too, and lists the names the globs let this client see.
"""

from __future__ import annotations

import asyncio
import inspect
import logging
from typing import TYPE_CHECKING

from protocol import foxglove as fg
from protocol import ops
from protocol.errors import ProtocolError

from ...backends import blame
from ...backends.base import BackendError
from ...rules.access import Action
from .hub import EMPTY, GONE, Service
from .topics import Dropped

if TYPE_CHECKING:
    from .session import FoxgloveSession

log = logging.getLogger('rosgate.foxglove')


# --- services ------------------------------------------------------------------------------------

def service_call(s: FoxgloveSession, op: fg.ServiceCallRequest) -> None:
    service = s.hub.service_ids.get(op.service_id) if op.service_id in s.offered_services else None
    if service is None:
        s.send(fg.service_call_failure(op.service_id, op.call_id,
                                       f'service {op.service_id} is not advertised to this client'))
        return
    try:
        s.admit(ops.CallService(service=service.name, id=str(op.call_id), type=service.type))
        if op.encoding != 'cdr':
            raise ProtocolError(f'encoding {op.encoding!r}: service calls are made in cdr')
        request = s.backend.from_cdr(service.srv.request.type, op.data)
    except Dropped:
        raise
    except Exception as e:   # noqa: BLE001 (refused, a request the backend cannot read, or a bug: answered)
        _failed(s, service, op, e)
        return
    s.spawn(_call(s, service, op, request), op.OP, str(op.call_id))


async def _call(s: FoxgloveSession, service: Service, op: fg.ServiceCallRequest, request: dict) -> None:
    try:
        own = s.gateway.own_services.get(service.name)
        if own is not None:   # answered by the gateway, knowing who asks (a station's claim)
            values = own[1](s, request)
            if inspect.isawaitable(values):
                values = await values
        else:
            timeout = s.gateway.settings.default_call_service_timeout
            values = await s.backend.call_service(service.name, service.type, request,
                                                  timeout if timeout > 0 else None)
        payload = s.backend.to_cdr(service.srv.response.type, values)
    except asyncio.CancelledError:
        raise
    except Exception as e:   # noqa: BLE001 (the caller always gets its answer; bugs are also logged)
        _failed(s, service, op, e)
        return
    s.send(fg.service_call_response(op.service_id, op.call_id, 'cdr', payload), binary=True)


def _failed(s: FoxgloveSession, service: Service, op: fg.ServiceCallRequest, exc: BaseException) -> None:
    if not blame.answerable(exc):
        log.error('internal error calling %s for foxglove client %s', service.name, s.id, exc_info=exc)
    s.send(fg.service_call_failure(op.service_id, op.call_id, f'{service.name}: {blame.sentence(exc)}'))


# --- parameters ----------------------------------------------------------------------------------

def _rule_name(s: FoxgloveSession, name: str, op) -> str:
    """'/node.param' as the rules name it ('/node:param'); a malformed name is refused."""
    try:
        node, param = fg.split_parameter(name)
    except ValueError as e:
        raise ProtocolError(str(e), op=op.OP, id=getattr(op, 'id', None)) from None
    return f'{node}:{param}'


def _readable(s: FoxgloveSession, op, work: bool = True) -> None:
    """A parameter or graph read: the gate, then the role's read permission."""
    s.gate(op.OP, getattr(op, 'id', None), work)
    s.require(Action.READ, None, op.OP, getattr(op, 'id', None))


async def _names(s: FoxgloveSession, op, names) -> list[str]:
    """The names asked for (every parameter of the graph for none), those the globs allow."""
    if not names:
        names = [fg.parameter_name(node, param) for node, _, param in
                 (n.partition(':') for n in await s.backend.param_names())]
    return [n for n in names if s.listed('params', _rule_name(s, n, op))]


def get_parameters(s: FoxgloveSession, op: fg.GetParameters) -> None:
    _readable(s, op)
    for name in op.names:
        _rule_name(s, name, op)

    async def answer() -> None:
        values = await s.hub.read(await _names(s, op, op.names))
        s.send(fg.parameter_values([fg.foxglove_parameter(n, v) for n, v in values.items()], op.id))

    s.spawn(answer(), op.OP, op.id)


def set_parameters(s: FoxgloveSession, op: fg.SetParameters) -> None:
    s.gate(op.OP, op.id, work=True)
    for p in op.parameters:
        s.require(Action.PARAM, _rule_name(s, p.name, op), op.OP, op.id)

    async def change() -> None:
        backend = s.backend
        for p in op.parameters:
            node, param = fg.split_parameter(p.name)
            try:
                if p.value is fg.UNSET:
                    await backend.delete_param(node, param)
                else:
                    await backend.set_param(node, param, p.ros_value())
            except (BackendError, KeyError) as e:
                why = f'{p.name} is not set' if isinstance(e, KeyError) else blame.sentence(e)
                s.status('error', why, op.OP, op.id)
        names = [p.name for p in op.parameters]
        values = await s.hub.read(names)
        s.hub.changed({n: values.get(n, GONE) for n in names})   # to the clients following them
        if op.id is not None:
            s.send(fg.parameter_values([fg.foxglove_parameter(n, v) for n, v in values.items()], op.id))

    s.spawn(change(), op.OP, op.id)


def subscribe_parameters(s: FoxgloveSession, op: fg.SubscribeParameterUpdates) -> None:
    _readable(s, op)
    for name in op.names:
        _rule_name(s, name, op)

    async def follow() -> None:   # the parameters that exist (a client cannot make the hub poll made-up names)
        s.param_subs.update(await s.hub.read(await _names(s, op, op.names)))

    s.spawn(follow(), op.OP, None)


def unsubscribe_parameters(s: FoxgloveSession, op: fg.UnsubscribeParameterUpdates) -> None:
    s.gate(op.OP)
    if op.names:
        s.param_subs.difference_update(op.names)
    else:
        s.param_subs.clear()


# --- the connection graph and what this server lacks -------------------------------------------

def subscribe_graph(s: FoxgloveSession, op: fg.SubscribeConnectionGraph) -> None:
    _readable(s, op, work=False)
    if s.graph is None:
        s.graph = EMPTY
        s.graph_changed(s.hub.graph())


def unsubscribe_graph(s: FoxgloveSession, op: fg.UnsubscribeConnectionGraph) -> None:
    s.gate(op.OP)
    s.graph = None


def fetch_asset(s: FoxgloveSession, op: fg.FetchAsset) -> None:
    s.gate(op.OP)
    s.send(fg.fetch_asset_response(op.request_id, error='this server has no assets capability'), binary=True)


CALLS = {
    fg.ServiceCallRequest: service_call,
    fg.GetParameters: get_parameters,
    fg.SetParameters: set_parameters,
    fg.SubscribeParameterUpdates: subscribe_parameters,
    fg.UnsubscribeParameterUpdates: unsubscribe_parameters,
    fg.SubscribeConnectionGraph: subscribe_graph,
    fg.UnsubscribeConnectionGraph: unsubscribe_graph,
    fg.FetchAsset: fetch_asset,
}
