"""Parameters of any node, through its rcl_interfaces services (get/set/list_parameters)."""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

from ..base import BackendError

if TYPE_CHECKING:
    from .backend import RclpyBackend

PARAM_NOT_SET, PARAM_DOUBLE, PARAM_DOUBLE_ARRAY = 0, 3, 8


async def _get_value(backend: RclpyBackend, node: str, name: str):
    from rcl_interfaces.srv import GetParameters  # noqa: PLC0415
    response = await backend.param_call(node, 'get_parameters', GetParameters,
                                        GetParameters.Request(names=[name]))
    return response.values[0] if response.values else None


async def get_param(backend: RclpyBackend, node: str, name: str) -> Any:
    """The value as plain Python; KeyError when the node has no such parameter."""
    from rclpy.parameter import parameter_value_to_python  # noqa: PLC0415
    value = await _get_value(backend, node, name)
    if value is None or value.type == PARAM_NOT_SET:
        raise KeyError(f'{node}:{name}')
    return plain(parameter_value_to_python(value))


async def set_param(backend: RclpyBackend, node: str, name: str, value: Any) -> None:
    from rclpy.parameter import Parameter  # noqa: PLC0415
    current = await _get_value(backend, node, name)
    kind = current.type if current is not None else PARAM_NOT_SET
    if kind == PARAM_DOUBLE and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)     # JSON '1' for a double parameter
    elif kind == PARAM_DOUBLE_ARRAY and isinstance(value, list):
        value = [float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    try:
        msg = Parameter(name, value=value).to_parameter_msg()
    except TypeError as e:
        raise BackendError(f'parameter {name}: {e}') from None
    await _set(backend, node, name, msg, 'set')


async def delete_param(backend: RclpyBackend, node: str, name: str) -> None:
    """ROS 2 has no delete: setting a parameter to NOT_SET undeclares it (where the node allows)."""
    from rcl_interfaces.msg import Parameter as ParameterMsg  # noqa: PLC0415
    await _set(backend, node, name, ParameterMsg(name=name), 'delete')


async def _set(backend: RclpyBackend, node: str, name: str, msg, verb: str) -> None:
    from rcl_interfaces.srv import SetParameters  # noqa: PLC0415
    response = await backend.param_call(node, 'set_parameters', SetParameters,
                                        SetParameters.Request(parameters=[msg]))
    result = response.results[0] if response.results else None
    if result is None or not result.successful:
        reason = result.reason if result is not None else 'no result'
        raise BackendError(f'cannot {verb} parameter {name} of {node}: {reason}')


async def param_names(backend: RclpyBackend) -> list[str]:
    """'/node:param' for every parameter of every node that lists its parameters."""
    from rcl_interfaces.srv import ListParameters  # noqa: PLC0415
    services = backend.served_types()
    nodes = [n for n in backend.nodes() if f'{n}/list_parameters' in services]

    async def names(node: str) -> list[str]:
        try:
            response = await backend.param_call(node, 'list_parameters', ListParameters,
                                                ListParameters.Request())
        except BackendError:
            return []   # the node left or does not answer
        return [f'{node}:{n}' for n in response.result.names]

    found = await asyncio.gather(*(names(n) for n in nodes))
    return sorted(name for group in found for name in group)


def plain(value):
    """Parameter values as plain Python (byte arrays arrive as 1-byte bytes objects)."""
    if isinstance(value, list):
        return [v[0] if isinstance(v, (bytes, bytearray)) else v for v in value]
    return value
