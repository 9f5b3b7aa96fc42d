"""Parameters of other nodes: get, set, delete, list."""

from __future__ import annotations

import pytest

from gateway.backends.base import BackendError

pytestmark = pytest.mark.asyncio(loop_scope='session')

NODE = '/fibonacci_action_server'


async def test_get_set(world):
    backend = world.backend
    interval = await backend.get_param(NODE, 'step_interval')
    assert isinstance(interval, float)
    try:
        await backend.set_param(NODE, 'step_interval', 0.07)
        assert await backend.get_param(NODE, 'step_interval') == 0.07
        await backend.set_param(NODE, 'step_interval', 1)    # an integer for a double: coerced
        value = await backend.get_param(NODE, 'step_interval')
        assert value == 1.0 and isinstance(value, float)
    finally:
        await backend.set_param(NODE, 'step_interval', interval)


async def test_wrong_type_rejected(world):
    with pytest.raises(BackendError):
        await world.backend.set_param(NODE, 'step_interval', 'fast')
    assert isinstance(await world.backend.get_param(NODE, 'step_interval'), float)


async def test_names(world):
    names = await world.backend.param_names()
    assert f'{NODE}:step_interval' in names
    assert all(':' in n and n.startswith('/') for n in names)


async def test_create_and_delete(world):
    backend = world.backend
    with pytest.raises(KeyError):
        await backend.get_param(NODE, 'scratch')
    await backend.set_param(NODE, 'scratch', ['a', 'b'])
    assert await backend.get_param(NODE, 'scratch') == ['a', 'b']
    assert f'{NODE}:scratch' in await backend.param_names()
    await backend.delete_param(NODE, 'scratch')
    with pytest.raises(KeyError):
        await backend.get_param(NODE, 'scratch')
    assert f'{NODE}:scratch' not in await backend.param_names()


async def test_unknown_node(world):
    with pytest.raises(BackendError):
        await world.backend.get_param('/no_such_node', 'x')
