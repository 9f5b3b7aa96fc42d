"""rclpy.parameter for Python in the IDE page: a node's parameters, kept in the node (the page's
node serves no parameter services to the graph)."""

import array
from enum import Enum

PARAMETER_SEPARATOR_STRING = "."


class ParameterValue:
    """rcl_interfaces/msg/ParameterValue as rclpy returns it: type and the *_value fields."""

    def __init__(self, type=0, bool_value=False, integer_value=0, double_value=0.0, string_value="",
                 byte_array_value=None, bool_array_value=None, integer_array_value=None,
                 double_array_value=None, string_array_value=None):
        self.type = type
        self.bool_value = bool_value
        self.integer_value = integer_value
        self.double_value = double_value
        self.string_value = string_value
        self.byte_array_value = byte_array_value or []
        self.bool_array_value = bool_array_value or []
        self.integer_array_value = integer_array_value or []
        self.double_array_value = double_array_value or []
        self.string_array_value = string_array_value or []

    def __repr__(self):
        return "rcl_interfaces.msg.ParameterValue(type=%d, ...)" % self.type


class SetParametersResult:
    def __init__(self, successful=False, reason=""):
        self.successful = successful
        self.reason = reason


class ParameterDescriptor:
    def __init__(self, name="", type=0, description="", additional_constraints="", read_only=False,
                 dynamic_typing=False, floating_point_range=None, integer_range=None):
        self.name, self.type, self.description = name, type, description
        self.additional_constraints, self.read_only, self.dynamic_typing = additional_constraints, read_only, dynamic_typing
        self.floating_point_range = floating_point_range or []
        self.integer_range = integer_range or []


class Parameter:
    class Type(Enum):
        NOT_SET = 0
        BOOL = 1
        INTEGER = 2
        DOUBLE = 3
        STRING = 4
        BYTE_ARRAY = 5
        BOOL_ARRAY = 6
        INTEGER_ARRAY = 7
        DOUBLE_ARRAY = 8
        STRING_ARRAY = 9

        @classmethod
        def from_parameter_value(cls, parameter_value):
            if parameter_value is None:
                return cls.NOT_SET
            if isinstance(parameter_value, bool):
                return cls.BOOL
            if isinstance(parameter_value, int):
                return cls.INTEGER
            if isinstance(parameter_value, float):
                return cls.DOUBLE
            if isinstance(parameter_value, str):
                return cls.STRING
            if isinstance(parameter_value, (list, tuple, array.array)):
                items = list(parameter_value)
                if all(isinstance(v, bytes) for v in items):
                    return cls.BYTE_ARRAY
                if all(isinstance(v, bool) for v in items):
                    return cls.BOOL_ARRAY
                if all(isinstance(v, int) for v in items):
                    return cls.INTEGER_ARRAY
                if all(isinstance(v, float) for v in items):
                    return cls.DOUBLE_ARRAY
                if all(isinstance(v, str) for v in items):
                    return cls.STRING_ARRAY
                raise TypeError("The given value is not a list of one of the allowed types '{}'.".format(parameter_value))
            raise TypeError("The given value is not one of the allowed types '{}'.".format(parameter_value))

        def check(self, parameter_value):
            try:
                return Parameter.Type.from_parameter_value(parameter_value) == self or (
                    self in (Parameter.Type.INTEGER_ARRAY, Parameter.Type.DOUBLE_ARRAY, Parameter.Type.BOOL_ARRAY,
                             Parameter.Type.STRING_ARRAY, Parameter.Type.BYTE_ARRAY)
                    and isinstance(parameter_value, (list, tuple)) and not parameter_value)
            except TypeError:
                return False

    def __init__(self, name, type_=None, value=None):
        if type_ is None:
            type_ = Parameter.Type.from_parameter_value(value)
        if not isinstance(type_, Parameter.Type):
            raise TypeError("type must be an instance of '{}'".format(repr(Parameter.Type)))
        if not type_.check(value) and not (type_ == Parameter.Type.NOT_SET and value is None):
            raise ValueError("Type '{}' and value '{}' do not agree".format(type_, value))
        self._type_ = type_
        self._name = name
        self._value = value

    @property
    def name(self):
        return self._name

    @property
    def value(self):
        return self._value

    @property
    def type_(self):
        return self._type_

    def get_parameter_value(self):
        t = self._type_
        v = self._value
        pv = ParameterValue(type=t.value)
        field = {Parameter.Type.BOOL: "bool_value", Parameter.Type.INTEGER: "integer_value",
                 Parameter.Type.DOUBLE: "double_value", Parameter.Type.STRING: "string_value",
                 Parameter.Type.BYTE_ARRAY: "byte_array_value", Parameter.Type.BOOL_ARRAY: "bool_array_value",
                 Parameter.Type.INTEGER_ARRAY: "integer_array_value",
                 Parameter.Type.DOUBLE_ARRAY: "double_array_value",
                 Parameter.Type.STRING_ARRAY: "string_array_value"}.get(t)
        if field is not None:
            setattr(pv, field, list(v) if isinstance(v, (list, tuple, array.array)) else v)
        return pv

    def to_parameter_msg(self):
        return self

    def __repr__(self):
        return "Parameter(name=%r, type_=%s, value=%r)" % (self._name, self._type_, self._value)


def parameter_value_to_python(parameter_value):
    t = Parameter.Type(parameter_value.type)
    return {Parameter.Type.NOT_SET: None, Parameter.Type.BOOL: parameter_value.bool_value,
            Parameter.Type.INTEGER: parameter_value.integer_value, Parameter.Type.DOUBLE: parameter_value.double_value,
            Parameter.Type.STRING: parameter_value.string_value,
            Parameter.Type.BYTE_ARRAY: parameter_value.byte_array_value,
            Parameter.Type.BOOL_ARRAY: parameter_value.bool_array_value,
            Parameter.Type.INTEGER_ARRAY: parameter_value.integer_array_value,
            Parameter.Type.DOUBLE_ARRAY: parameter_value.double_array_value,
            Parameter.Type.STRING_ARRAY: parameter_value.string_array_value}[t]
