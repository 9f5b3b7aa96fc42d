"""The parameter services every node of the sim graph offers, as every rclpy and rclcpp node does:
``<node>/list_parameters``, ``get_parameters``, ``get_parameter_types``, ``describe_parameters``,
``set_parameters`` and ``set_parameters_atomically`` (rcl_interfaces/srv), answered from the node's
``params`` as rclpy's ``ParameterService`` answers. So a tool that reads or sets a real node's
parameters through these services (``ros2 param``, the /inspect page) works on the sim unchanged.

As rclpy with its defaults: a parameter must be declared before it is set (``parameter not
declared``), keeps its type (an integer for a double is taken as a double: rosapi's JSON
cannot tell ``1`` from ``1.0``), and a value of type NOT_SET undeclares it. A node's own check
(``declare_parameter(on_set=...)``: the rover's limits) refuses a value with a reason.
"""

from __future__ import annotations

from typing import Any

from ..base import BackendError

NOT_SET, BOOL, INTEGER, DOUBLE, STRING, BYTE_ARRAY, BOOL_ARRAY, INTEGER_ARRAY, DOUBLE_ARRAY, STRING_ARRAY = range(10)
TYPE_NAMES = ('not set', 'bool', 'integer', 'double', 'string', 'byte array', 'bool array',
              'integer array', 'double array', 'string array')
FIELDS = {BOOL: 'bool_value', INTEGER: 'integer_value', DOUBLE: 'double_value', STRING: 'string_value',
          BYTE_ARRAY: 'byte_array_value', BOOL_ARRAY: 'bool_array_value', INTEGER_ARRAY: 'integer_array_value',
          DOUBLE_ARRAY: 'double_array_value', STRING_ARRAY: 'string_array_value'}
SERVICES = {
    'list_parameters': 'rcl_interfaces/srv/ListParameters',
    'get_parameters': 'rcl_interfaces/srv/GetParameters',
    'get_parameter_types': 'rcl_interfaces/srv/GetParameterTypes',
    'describe_parameters': 'rcl_interfaces/srv/DescribeParameters',
    'set_parameters': 'rcl_interfaces/srv/SetParameters',
    'set_parameters_atomically': 'rcl_interfaces/srv/SetParametersAtomically',
}
SEPARATOR = '.'


def kind_of(value: Any) -> int:
    """The ParameterType of a plain Python value (an empty list: a string array, as rclpy says)."""
    if value is None:
        return NOT_SET
    if isinstance(value, bool):
        return BOOL
    if isinstance(value, int):
        return INTEGER
    if isinstance(value, float):
        return DOUBLE
    if isinstance(value, str):
        return STRING
    if isinstance(value, (bytes, bytearray)):
        return BYTE_ARRAY
    if isinstance(value, (list, tuple)):
        kinds = {kind_of(v) for v in value}
        if kinds <= {BOOL}:
            return BOOL_ARRAY if value else STRING_ARRAY
        if kinds <= {INTEGER}:
            return INTEGER_ARRAY
        if kinds <= {INTEGER, DOUBLE}:
            return DOUBLE_ARRAY
        if kinds <= {STRING}:
            return STRING_ARRAY
    raise BackendError(f'a parameter cannot hold {type(value).__name__} {value!r}')


def to_message(value: Any) -> dict:
    """rcl_interfaces/msg/ParameterValue of a plain value, every field present."""
    kind = kind_of(value)
    msg = {'type': kind, 'bool_value': False, 'integer_value': 0, 'double_value': 0.0, 'string_value': '',
           'byte_array_value': b'', 'bool_array_value': [], 'integer_array_value': [], 'double_array_value': [],
           'string_array_value': []}
    if kind == DOUBLE_ARRAY:
        value = [float(v) for v in value]
    elif kind == BYTE_ARRAY:
        value = bytes(value)
    elif kind in (BOOL_ARRAY, INTEGER_ARRAY, STRING_ARRAY):
        value = list(value)
    if kind != NOT_SET:
        msg[FIELDS[kind]] = value
    return msg


def from_message(msg: dict) -> Any:
    """The plain value a ParameterValue holds (None for NOT_SET)."""
    kind = msg.get('type', NOT_SET)
    if kind == NOT_SET:
        return None
    if kind not in FIELDS:
        raise BackendError(f'unknown parameter type {kind}')
    value = msg.get(FIELDS[kind])
    if kind == BYTE_ARRAY:
        return bytes(value or b'')
    return list(value) if isinstance(value, (list, tuple)) else value


class ParameterServices:
    """The six services of one sim node (``node.params`` and its checks answer them)."""

    def __init__(self, node):
        self.node = node
        self.kinds: dict[str, int] = {}   # a declared parameter's type (an empty list keeps its kind)
        node.params.setdefault('use_sim_time', False)   # every ROS 2 node declares it
        for short, type in SERVICES.items():
            node.create_service(f'{node.name}/{short}', type, getattr(self, short))

    def kind(self, name: str) -> int:
        if name not in self.kinds:
            self.kinds[name] = kind_of(self.node.params.get(name))
        return self.kinds[name]

    def list_parameters(self, request: dict) -> dict:
        prefixes = [p for p in request.get('prefixes') or () if p]
        depth = request.get('depth', 0)
        names, found = [], set()
        for name in sorted(self.node.params):
            if prefixes and not any(name == p or name.startswith(p + SEPARATOR) for p in prefixes):
                continue
            parts = name.split(SEPARATOR)
            if depth and len(parts) > depth:
                continue
            names.append(name)
            if len(parts) > 1:
                found.add(SEPARATOR.join(parts[:-1]))
        return {'result': {'names': names, 'prefixes': sorted(found)}}

    def get_parameters(self, request: dict) -> dict:
        params = self.node.params
        return {'values': [to_message(params.get(n)) for n in request.get('names') or ()]}

    def get_parameter_types(self, request: dict) -> dict:
        return {'types': [self.kind(n) if n in self.node.params else NOT_SET for n in request.get('names') or ()]}

    def describe_parameters(self, request: dict) -> dict:
        return {'descriptors': [self.descriptor(n) for n in request.get('names') or ()]}

    def descriptor(self, name: str) -> dict:
        described = self.node.param_descriptions.get(name, {})
        return {'name': name, 'type': self.kind(name) if name in self.node.params else NOT_SET,
                'description': described.get('description', ''), 'additional_constraints': described.get('constraints', ''),
                'read_only': bool(described.get('read_only', False)), 'dynamic_typing': False,
                'floating_point_range': [], 'integer_range': []}

    def set_parameters(self, request: dict) -> dict:
        return {'results': [self.set_one(p) for p in request.get('parameters') or ()]}

    def set_parameters_atomically(self, request: dict) -> dict:
        parameters = request.get('parameters') or ()
        for p in parameters:   # all or nothing: each judged before any is set
            why = self.refusal(p.get('name', ''), from_message(p.get('value') or {}))
            if why:
                return {'result': {'successful': False, 'reason': why}}
        results = [self.set_one(p) for p in parameters]
        failed = next((r for r in results if not r['successful']), None)
        return {'result': failed or {'successful': True, 'reason': ''}}

    def refusal(self, name: str, value: Any) -> str:
        """Why rclpy would not set ``name`` to ``value`` ('' : it would)."""
        if name not in self.node.params:
            return f'parameter {name} not declared' if value is not None else ''
        if self.node.param_descriptions.get(name, {}).get('read_only'):
            return f'parameter {name} cannot be set because it is read-only'
        if value is None:
            return ''
        have, want = self.kind(name), kind_of(value)
        if have == want or (have == DOUBLE and want == INTEGER) or (have == DOUBLE_ARRAY and want == INTEGER_ARRAY):
            return ''
        if have in (BOOL_ARRAY, INTEGER_ARRAY, DOUBLE_ARRAY, STRING_ARRAY) and value == []:
            return ''
        return (f'Wrong parameter type, parameter {{{name}}} is of type {{{TYPE_NAMES[have]}}}, '
                f'setting it to {{{TYPE_NAMES[want]}}} is not allowed.')

    def set_one(self, parameter: dict) -> dict:
        name = parameter.get('name', '')
        try:
            value = from_message(parameter.get('value') or {})
            why = self.refusal(name, value)
            if why:
                return {'successful': False, 'reason': why}
            if value is None:
                self.node.params.pop(name, None)
                self.kinds.pop(name, None)
            else:
                if self.kind(name) == DOUBLE_ARRAY:
                    value = [float(v) for v in value]
                self.node.set_parameter(name, value)
        except BackendError as e:
            return {'successful': False, 'reason': str(e)}
        return {'successful': True, 'reason': ''}
