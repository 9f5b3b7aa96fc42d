"""call_service, advertise_service, service_response, unadvertise_service."""

from __future__ import annotations

from typing import TYPE_CHECKING

import asyncio
import inspect

from protocol.convert import from_args, from_json
from protocol.errors import ProtocolError
from protocol.msgdefs import normalize
from protocol.ops import AdvertiseService, CallService, ServiceResponse, UnadvertiseService

from ...backends import blame
from .. import rosapi
from ...backends.base import SERVER_WAIT, BackendError
from .actions import sent_through_hidden_service
from .topics import absolute, unadvertised

if TYPE_CHECKING:
    from ..session import ClientSession


def call_service(s: ClientSession, op: CallService) -> None:
    s.spawn(_call(s, op), op.OP, op.id)


async def _call(s: ClientSession, op: CallService) -> None:
    name = absolute(op.service)
    reply = {'op': 'service_response', 'service': op.service, 'id': op.id}
    try:
        own = s.gateway.own_services.get(name)
        if rosapi.handles(name):
            values = await rosapi.call(s, name, op.args)
            srv = None
        elif own is not None:   # answered by the gateway, knowing who asks (a station's claim)
            type, answer = own
            srv = s.backend.srv_def(type)
            values = answer(s, from_args(s.backend.defs, srv.request, op.args))
            if inspect.isawaitable(values):   # an answer that waits (a fleet's claim, on PostgreSQL)
                values = await values
        else:
            type = normalize(op.type, 'srv') if op.type else await service_type(s, name)
            srv = s.backend.srv_def(type)
            request = from_args(s.backend.defs, srv.request, op.args)
            timeout = op.timeout if op.timeout is not None else s.gateway.settings.default_call_service_timeout
            values = await s.backend.call_service(name, type, request, timeout if timeout > 0 else None)
            sent_through_hidden_service(s, name, request, values)
    except asyncio.CancelledError:
        raise
    except Exception as e:   # the caller always gets its reply; bugs are also logged
        s.reply({**reply, 'values': blame.sentence(e), 'result': False})
        if not blame.answerable(e):
            s.report(op.OP, op.id, e)
        return
    s.reply({**reply, 'values': values, 'result': True}, op.compression, op.fragment_size,
            msgdef=srv.response if srv else None, defs=s.backend.defs, body='values')


async def service_type(s: ClientSession, name: str) -> str:
    """The type of a service with a server (one just created may take a moment to be discovered)."""
    if name in s.gateway.own_services:
        return s.gateway.own_services[name][0]
    types = await s.backend.wait_for_service(name, SERVER_WAIT)
    if not types:
        raise BackendError(f'service {name} does not exist')
    return types[0]


def advertise_service(s: ClientSession, op: AdvertiseService) -> None:
    name = absolute(op.service)
    if rosapi.handles(name) or name in s.gateway.own_services:   # calls would still reach the gateway
        raise ProtocolError(f'{name} is served by the gateway itself', op=op.OP, id=op.id)
    type = normalize(op.type, 'srv')
    srv = s.backend.srv_def(type)
    owner = s.gateway.service_owners.get(name)
    if owner is not None and owner is not s:   # re-advertising replaces, as in rosbridge
        owner.status('warning', f'{name} was advertised again by another client', op.OP)
        _release(owner, name)
    elif name in s.services:
        _release(s, name)

    async def handler(request: dict) -> dict:
        rid = f'service_request:{name}:{next(s._counter)}'
        fut = asyncio.get_running_loop().create_future()
        s.service_requests[rid] = (fut, srv)
        # the name as the client advertised it: roslibjs and roslibpy route requests by it
        s.reply({'op': 'call_service', 'id': rid, 'service': op.service, 'args': request})
        try:
            return await asyncio.wait_for(fut, s.gateway.settings.default_call_service_timeout)
        except asyncio.TimeoutError:
            raise BackendError(f'the client serving {name} did not answer in time') from None
        finally:
            s.service_requests.pop(rid, None)

    s.services[name] = (s.backend.advertise_service(name, type, handler), srv)
    s.gateway.service_owners[name] = s


def service_response(s: ClientSession, op: ServiceResponse) -> None:
    pending = s.service_requests.pop(op.id, None) if op.id else None
    if pending is None:
        s.status('warning', 'no request with this id is waiting for a response', op.OP, op.id)
        return
    fut, srv = pending
    if fut.done():
        return
    if op.result is False:
        fut.set_exception(BackendError(str(op.values) if op.values else 'the serving client failed the call'))
        return
    try:
        values = from_json(s.backend.defs, srv.response, op.values if isinstance(op.values, dict) else {})
    except ProtocolError as e:
        fut.set_exception(BackendError(f'invalid response from the serving client: {e.message}'))
        raise
    fut.set_result(values)


def unadvertise_service(s: ClientSession, op: UnadvertiseService) -> None:
    unadvertised(s, absolute(op.service), s.services, op, _release)


def _release(s: ClientSession, name: str) -> None:
    handle, _ = s.services.pop(name)
    if s.gateway.service_owners.get(name) is s:
        del s.gateway.service_owners[name]
    for rid, (fut, _) in list(s.service_requests.items()):
        if rid.startswith(f'service_request:{name}:') and not fut.done():
            fut.set_exception(BackendError(f'{name} was unadvertised'))
    handle.destroy()
