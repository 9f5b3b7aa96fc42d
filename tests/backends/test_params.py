"""Parameters of other nodes: get, set, delete, list."""

from __future__ import annotations

import pytest

from gateway.backends.base import BackendError

pytestmark = pytest.mark.asyncio(loop_scope='session')

NODE = '/fibonacci_action_server'
ADDER = '/add_two_ints_server'


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


# --- the node's own rcl_interfaces services, as `ros2 param` and the /inspect page use them ----------

async def _call(backend, service: str, request: dict) -> dict:
    short = service.rsplit('/', 1)[1]
    type = 'rcl_interfaces/srv/' + ''.join(w.capitalize() for w in short.split('_'))
    return await backend.call_service(service, type, request, 5.0)


async def test_parameter_services_list_get_describe(world):
    backend = world.backend
    services = dict(backend.services())
    for short in ('list_parameters', 'get_parameters', 'get_parameter_types', 'describe_parameters',
                  'set_parameters', 'set_parameters_atomically'):
        assert services.get(f'{NODE}/{short}', '').startswith('rcl_interfaces/srv/'), short
    listed = await _call(backend, f'{NODE}/list_parameters', {'prefixes': [], 'depth': 0})
    assert 'step_interval' in listed['result']['names']
    got = await _call(backend, f'{NODE}/get_parameters', {'names': ['step_interval', 'no_such_parameter']})
    assert got['values'][0]['type'] == 3 and isinstance(got['values'][0]['double_value'], float)
    assert got['values'][1]['type'] == 0                      # NOT_SET, as rclpy answers an unknown name
    types = await _call(backend, f'{NODE}/get_parameter_types', {'names': ['step_interval']})
    assert list(types['types']) == [3]
    described = await _call(backend, f'{NODE}/describe_parameters', {'names': ['step_interval']})
    assert described['descriptors'][0]['name'] == 'step_interval' and described['descriptors'][0]['type'] == 3


async def test_parameter_services_set(world):
    backend = world.backend
    before = await backend.get_param(NODE, 'step_interval')
    double = {'type': 3, 'double_value': 0.09}
    try:
        done = await _call(backend, f'{NODE}/set_parameters', {'parameters': [
            {'name': 'step_interval', 'value': double},
            {'name': 'step_interval', 'value': {'type': 4, 'string_value': 'fast'}}]})   # another type: refused
        ok, wrong = done['results']
        assert ok == {'successful': True, 'reason': ''}
        assert not wrong['successful'] and 'type' in wrong['reason']
        assert await backend.get_param(NODE, 'step_interval') == 0.09
        # a node with ROS 2's defaults (every node has use_sim_time) takes no parameter it did not declare,
        # and an atomic set is all or nothing
        undeclared = {'name': 'not_declared_here', 'value': {'type': 2, 'integer_value': 1}}
        done = await _call(backend, f'{ADDER}/set_parameters', {'parameters': [undeclared]})
        assert not done['results'][0]['successful'] and 'declared' in done['results'][0]['reason']
        atomic = await _call(backend, f'{ADDER}/set_parameters_atomically', {'parameters': [
            {'name': 'use_sim_time', 'value': {'type': 1, 'bool_value': True}}, undeclared]})
        assert not atomic['result']['successful']
        assert await backend.get_param(ADDER, 'use_sim_time') is False
    finally:
        await backend.set_param(NODE, 'step_interval', before)
