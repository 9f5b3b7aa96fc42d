"""The doors media/ and twin/ are given (their ports, typed as Protocols) are what the server hands
them: every member a port names is on the object handed in, and every call a port declares binds
to that object's own signature (a renamed method or parameter fails here, in-process, not in a
gateway at run time). The objects are the real ones, of an in-process gateway on the sim backend
with a fleet, the lease and sign-in (the policy's lease, stations and tokens are there)."""

from __future__ import annotations

import inspect

import pytest

from gateway.backends.base import QoS
from gateway.bridge.taps import Senders, Taps
from gateway.media import ports as media
from gateway.store.fleet import Fleet
from gateway.twin import ports as twin
from tests.support.auth import tokens_toml
from tests.support.inproc import InProcess

STRING = 'std_msgs/msg/String'


def members(port: type) -> dict[str, object]:
    """What a port names: its annotated attributes (None) and its calls (the function)."""
    found: dict[str, object] = {}
    for cls in reversed(port.__mro__):
        if cls.__module__ in ('typing', 'builtins', 'abc'):
            continue
        found.update({name: None for name in getattr(cls, '__annotations__', {})})
        found.update({name: f for name, f in vars(cls).items() if inspect.isfunction(f) and not name.startswith('_')})
    return found


def unmet(port: type, obj: object) -> list[str]:
    """Where ``obj`` is not the ``port``: a member missing, or a declared call that does not bind."""
    wrong, mine = [], getattr(obj, '__name__', type(obj).__name__)
    for name, declared in members(port).items():
        if not hasattr(obj, name):
            wrong.append(f'{port.__name__}.{name}: {mine} has none')
            continue
        if declared is None:
            continue
        got = getattr(obj, name)
        if not callable(got):
            wrong.append(f'{port.__name__}.{name}: not a call on {mine}')
            continue
        params = list(inspect.signature(declared).parameters.values())[1:]   # without self
        args = [object() for p in params if p.kind == p.POSITIONAL_OR_KEYWORD and p.default is p.empty]
        kwargs = {p.name: object() for p in params if p.kind == p.KEYWORD_ONLY
                  or (p.kind == p.POSITIONAL_OR_KEYWORD and p.default is not p.empty)}
        try:
            inspect.signature(got).bind(*args, **kwargs)
        except TypeError as e:
            wrong.append(f'{port.__name__}.{name}{inspect.signature(declared)}: {mine}\'s does not take it ({e})')
    return wrong


@pytest.fixture(scope='module')
def tokens(tmp_path_factory):
    path = tmp_path_factory.mktemp('doors') / 'tokens.toml'
    path.write_text(tokens_toml())
    return str(path)


async def test_the_rooms_doors_are_what_the_server_hands_them(tokens):
    async with InProcess('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control', '--auth', tokens) as gw:
        g, backend, policy = gw.gateway, gw.backend, gw.policy
        fan = g.fanout('/s01/turtle1/pose', 'turtlesim/msg/Pose')
        try:
            pairs = [
                (media.Taps, Taps(g)), (media.Senders, Senders(g)), (media.Graph, backend), (media.Types, backend),
                (media.Names, policy), (media.Lease, policy.lease), (media.StationNames, policy.lease.names),
                (media.Fanout, fan), (media.Outlet, g.publisher('/doors', STRING, QoS())),
                (twin.Taps, Taps(g)), (twin.Backend, backend), (twin.Names, policy), (twin.SignIn, policy),
                (twin.Tokens, policy.auth), (twin.Stations, policy.stations), (twin.Store, g.store),
                (twin.Timekeeper, Fleet), (twin.Points, g.hooks), (twin.Fanout, fan),
            ]
            assert all(members(port) for port, _ in pairs)
            wrong = [w for port, obj in pairs for w in unmet(port, obj)]
        finally:
            g.drop_fanout(fan)
    assert wrong == []


def test_the_check_sees_a_door_that_is_not_there():
    class Near:
        topics = 'a list, not a call'

        def fanout(self, topic):   # one parameter short
            return None

    assert unmet(media.Taps, Near()) and 'does not take it' in unmet(media.Taps, Near())[0]
    assert unmet(media.Graph, Near()) == ['Graph.topics: not a call on Near']
    assert unmet(media.Types, Near())[0] == 'Types.msg_def: Near has none'
    assert unmet(media.Taps, Taps.__new__(Taps)) == ['Taps.fanout: Taps has none']
