"""ROS 2 message, service and action classes for Python in the IDE page, made from the gateway's
own type definitions (rosapi's ``message_details``, ``service_request_details`` ...) the first
time a program imports them: ``from geometry_msgs.msg import Twist`` works for any type the
gateway knows, as it does on a ROS 2 machine where rosidl generated the class.

The classes behave as rosidl's Python classes do where a program can tell: keyword constructors,
``get_fields_and_field_types()``, constants as class attributes, fields checked on assignment with
rosidl's own messages (``The 'x' field must be of type 'float'``), numeric sequences as
``array.array``, ``Srv.Request`` / ``Srv.Response``, ``Action.Goal`` / ``Result`` / ``Feedback``,
equality and repr. A program that runs here runs unchanged under rclpy.

``to_json`` and ``from_json`` turn them into rosbridge's JSON shapes and back (the page's
connection carries JSON: a float that is a whole number arrives as an int and becomes a float
again here, by its field's type).
"""

import array
import base64
import importlib.abc
import importlib.machinery
import math
import sys
import types

KINDS = ("msg", "srv", "action")
# rosapi's primitive names -> (rclpy's name in get_fields_and_field_types, array typecode, kind)
PRIMITIVES = {
    "float64": ("double", "d", "float"), "float32": ("float", "f", "float"),
    "double": ("double", "d", "float"), "float": ("float", "f", "float"),
    "int8": ("int8", "b", "int"), "uint8": ("uint8", "B", "int"), "int16": ("int16", "h", "int"),
    "uint16": ("uint16", "H", "int"), "int32": ("int32", "i", "int"), "uint32": ("uint32", "I", "int"),
    "int64": ("int64", "q", "int"), "uint64": ("uint64", "Q", "int"),
    "byte": ("octet", "B", "int"), "octet": ("octet", "B", "int"), "char": ("uint8", "B", "int"),
    "bool": ("boolean", None, "bool"), "boolean": ("boolean", None, "bool"),
    "string": ("string", None, "str"), "wstring": ("wstring", None, "str"),
}
INT_RANGE = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}
UINT_RANGE = {"uint8": 8, "octet": 8, "uint16": 16, "uint32": 32, "uint64": 64}
FLOAT32_MAX = 3.4028234663852886e38
FLOAT64_MAX = 1.7976931348623157e308


class Field:
    """One field: its name, element type (a primitive name or a message class), and array shape
    (None: not an array, 0: a sequence, N: a fixed array of N)."""

    __slots__ = ("name", "base", "cls", "array", "rclpy_type", "typecode", "kind")

    def __init__(self, name, base, cls, array_len):
        self.name, self.base, self.cls = name, base, cls
        self.array = None if array_len is None or array_len < 0 else array_len
        if cls is None:
            self.rclpy_type, self.typecode, self.kind = PRIMITIVES.get(base, (base, None, "str"))
        else:
            pkg, _, name_ = cls._type.split("/")
            self.rclpy_type, self.typecode, self.kind = "%s/%s" % (pkg, name_), None, "msg"
        if self.array is not None:
            self.rclpy_type = ("%s[%d]" % (self.rclpy_type, self.array) if self.array
                               else "sequence<%s>" % self.rclpy_type)

    def default(self):
        if self.array is not None:
            n = self.array or 0
            if self.typecode:
                return array.array(self.typecode, [0] * n)
            return [self._scalar_default() for _ in range(n)]
        return self._scalar_default()

    def _scalar_default(self):
        return {"float": 0.0, "int": 0, "bool": False, "str": ""}.get(self.kind) if self.cls is None else self.cls()

    # rosidl's checks, with its words
    def check(self, value):
        if self.array is None:
            return self._one(value)
        if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
            raise AssertionError("The '%s' field must be a set or sequence and each value of type '%s'"
                                 % (self.name, self._python_name()))
        items = list(value)
        if self.array and len(items) != self.array:
            raise AssertionError("The '%s' field must be a set or sequence with length %d" % (self.name, self.array))
        items = [self._one(v) for v in items]
        return array.array(self.typecode, items) if self.typecode else items

    def _python_name(self):
        return self.cls.__name__ if self.cls is not None else {"float": "float", "int": "int", "bool": "bool", "str": "str"}[self.kind]

    def _one(self, v):
        name = self.name
        if self.cls is not None:
            if not isinstance(v, self.cls):
                raise AssertionError("The '%s' field must be a sub message of type '%s'" % (name, self.cls.__name__))
            return v
        if self.kind == "float":
            if not isinstance(v, float):
                raise AssertionError("The '%s' field must be of type 'float'" % name)
            top = FLOAT32_MAX if self.base in ("float32", "float") else FLOAT64_MAX
            if (v < -top or v > top) and not math.isinf(v):
                raise AssertionError("The '%s' field must be a %s in [%r, %r]" % (name, self.rclpy_type, -top, top))
            return v
        if self.kind == "int":
            if not isinstance(v, int):
                raise AssertionError("The '%s' field must be of type 'int'" % name)
            lo, hi = _int_range(self.base)
            if not lo <= v <= hi:
                raise AssertionError("The '%s' field must be an unsigned integer in [%d, %d]" % (name, lo, hi)
                                     if lo == 0 else "The '%s' field must be an integer in [%d, %d]" % (name, lo, hi))
            return v
        if self.kind == "bool":
            if not isinstance(v, bool):
                raise AssertionError("The '%s' field must be of type 'bool'" % name)
            return v
        if not isinstance(v, str):
            raise AssertionError("The '%s' field must be of type 'str'" % name)
        return v


def _int_range(base):
    if base in UINT_RANGE:
        return 0, 2 ** UINT_RANGE[base] - 1
    bits = INT_RANGE.get(base, 64)
    return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1


class Message:
    """The base of every generated class (rosidl's classes have none; nothing relies on it)."""

    __slots__ = ()
    _type = ""
    _fields = ()

    def __init__(self, **kwargs):
        unknown = [k for k in kwargs if k not in self._by_name]
        if unknown:
            raise AssertionError("Invalid arguments passed to constructor: %s" % ", ".join(sorted(unknown)))
        for f in self._fields:
            if f.name in kwargs:
                setattr(self, f.name, kwargs[f.name])
            else:
                object.__setattr__(self, "_" + f.name, f.default())

    @classmethod
    def get_fields_and_field_types(cls):
        return {f.name: f.rclpy_type for f in cls._fields}

    def __eq__(self, other):
        if not isinstance(other, self.__class__):
            return False
        return all(getattr(self, f.name) == getattr(other, f.name) for f in self._fields)

    def __repr__(self):
        pkg, kind, name = self._type.split("/")
        args = ", ".join("%s=%r" % (f.name, getattr(self, f.name)) for f in self._fields)
        return "%s.%s.%s(%s)" % (pkg, kind, name, args)

    def __copy__(self):
        return from_json(self.__class__, to_json(self))

    def __deepcopy__(self, memo):
        return self.__copy__()


def _property(field):
    private = "_" + field.name

    def get(self):
        return getattr(self, private)

    def set(self, value):
        object.__setattr__(self, private, field.check(value))
    return property(get, set)


def _constant(text):
    for conv in (int, float):
        try:
            return conv(text)
        except (TypeError, ValueError):
            pass
    if text in ("True", "False"):
        return text == "True"
    return text


def make_class(full_type, typedef, nested):
    """A class for full_type ('pkg/msg/Name', 'pkg/srv/Name_Request' ...) from its rosapi TypeDef;
    nested(short_type) gives the class of a field's message type."""
    pkg, kind, name = full_type.split("/")
    fields = []
    for i, fname in enumerate(typedef["fieldnames"]):
        ftype = typedef["fieldtypes"][i]
        base = ftype.split("<=")[0]
        cls = None if base in PRIMITIVES else nested(base)
        fields.append(Field(fname, base, cls, typedef["fieldarraylen"][i]))
    namespace = {"__slots__": tuple("_" + f.name for f in fields), "_type": full_type, "_fields": tuple(fields),
                 "_by_name": {f.name: f for f in fields}, "__module__": "%s.%s" % (pkg, kind)}
    for f in fields:
        namespace[f.name] = _property(f)
    for cname, cvalue in zip(typedef.get("constnames") or [], typedef.get("constvalues") or []):
        namespace[cname] = _constant(cvalue)
    cls = type(name, (Message,), namespace)
    cls.__qualname__ = name
    return cls


# ---- rosbridge JSON ---------------------------------------------------------------------------

def to_json(msg):
    """A message as rosbridge JSON: nested dicts, lists of numbers."""
    out = {}
    for f in msg._fields:
        v = getattr(msg, f.name)
        if f.array is not None:
            out[f.name] = [to_json(x) for x in v] if f.cls is not None else [_plain(x) for x in v]
        else:
            out[f.name] = to_json(v) if f.cls is not None else _plain(v)
    return out


def _plain(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None   # what rosbridge JSON carries for NaN and infinities
    return v


def from_json(cls, values):
    """A message of class cls from rosbridge JSON (a missing field keeps its default)."""
    msg = cls()
    if not isinstance(values, dict):
        return msg
    for f in cls._fields:
        if f.name not in values:
            continue
        v = values[f.name]
        if f.array is not None:
            if isinstance(v, str) and f.typecode == "B":     # uint8[] as base64
                v = list(base64.b64decode(v))
            if v is None:
                continue
            v = [from_json(f.cls, x) for x in v] if f.cls is not None else [_scalar(f, x) for x in v]
        elif f.cls is not None:
            v = from_json(f.cls, v)
        else:
            v = _scalar(f, v)
        object.__setattr__(msg, "_" + f.name, f.check(v))
    return msg


def _scalar(f, v):
    if f.kind == "float":
        return math.nan if v is None else float(v)
    if f.kind == "int":
        return int(v)
    if f.kind == "bool":
        return bool(v)
    return "" if v is None else str(v)


# ---- the classes, made on demand ----------------------------------------------------------------

class Interfaces:
    """The classes of one run: fetch(service, type) -> rosapi's typedefs (a blocking call through
    the page's connection); packages() -> the set of ROS packages the gateway knows, or None."""

    def __init__(self, fetch, packages):
        self._fetch = fetch
        self._packages = packages
        self._known = None
        self.classes = {}                # full type -> class

    def is_package(self, name):
        if self._known is None:
            self._known = self._packages()
            if self._known is None:      # the gateway cannot list them: a name as ROS packages are named
                self._known = PackageNames()
        return name in self._known

    def message(self, full_type):
        if full_type not in self.classes:
            self._build(full_type, self._fetch("message_details", full_type))
        return self.classes[full_type]

    def _build(self, full_type, typedefs):
        """The class of typedefs[0] (as full_type) and of every message type nested in it."""
        by_short = {d["type"]: d for d in typedefs}

        def nested(short):
            full = _full(short)
            if full not in self.classes:
                d = by_short.get(short)
                if d is None:
                    return self.message(full)
                self.classes[full] = make_class(full, d, nested)
            return self.classes[full]
        root = make_class(full_type, typedefs[0], nested)
        self.classes[full_type] = root
        return root

    def service(self, full_type):
        if full_type not in self.classes:
            request = self._build(full_type + "_Request", self._fetch("service_request_details", full_type))
            response = self._build(full_type + "_Response", self._fetch("service_response_details", full_type))
            pkg, kind, name = full_type.split("/")
            request.__name__ = request.__qualname__ = name + "_Request"
            response.__name__ = response.__qualname__ = name + "_Response"
            self.classes[full_type] = type(name, (), {"Request": request, "Response": response, "_type": full_type,
                                                      "__module__": "%s.%s" % (pkg, kind)})
        return self.classes[full_type]

    def action(self, full_type):
        if full_type not in self.classes:
            parts = {}
            for part, service in (("Goal", "action_goal_details"), ("Result", "action_result_details"),
                                  ("Feedback", "action_feedback_details")):
                parts[part] = self._build("%s_%s" % (full_type, part), self._fetch(service, full_type))
            pkg, kind, name = full_type.split("/")
            feedback_message = type(name + "_FeedbackMessage", (), {
                "__slots__": ("goal_id", "feedback"), "__module__": "%s.%s" % (pkg, kind),
                "__init__": lambda self, goal_id=None, feedback=None: (
                    setattr(self, "goal_id", goal_id), setattr(self, "feedback", feedback)) and None,
                "__repr__": lambda self: "%s.%s.%s_FeedbackMessage(goal_id=%r, feedback=%r)" % (
                    pkg, kind, name, self.goal_id, self.feedback)})
            get_result = type(name + "_GetResult_Response", (), {
                "__slots__": ("status", "result"), "__module__": "%s.%s" % (pkg, kind),
                "__init__": lambda self, status=0, result=None: (
                    setattr(self, "status", status), setattr(self, "result", result)) and None,
                "__repr__": lambda self: "%s.%s.%s_GetResult_Response(status=%r, result=%r)" % (
                    pkg, kind, name, self.status, self.result)})
            impl = type("Impl", (), {"FeedbackMessage": feedback_message, "GetResultService": type(
                name + "_GetResult", (), {"Response": get_result})})
            self.classes[full_type] = type(name, (), {**parts, "Impl": impl, "_type": full_type,
                                                      "__module__": "%s.%s" % (pkg, kind)})
        return self.classes[full_type]


class PackageNames:
    """Any name shaped as a ROS package's (lower case, digits and '_'), when the gateway cannot
    list its packages: a module no other finder has is looked for as one."""

    def __contains__(self, name):
        return bool(name) and name[0].isalpha() and name == name.lower() and name.replace("_", "").isalnum()


def _full(short):
    """'geometry_msgs/Vector3' -> 'geometry_msgs/msg/Vector3' (a nested field's type is a message)."""
    parts = short.split("/")
    return short if len(parts) == 3 else "%s/msg/%s" % (parts[0], parts[-1])


def type_name(cls):
    """The rosbridge type of a class: 'std_msgs/msg/String'; TypeError for anything else."""
    name = getattr(cls, "_type", None)
    if not isinstance(name, str) or name.count("/") != 2:
        raise TypeError("%r is not a ROS message, service or action type" % (cls,))
    return name


class _KindModule(types.ModuleType):
    """PKG.msg, PKG.srv or PKG.action: its names are the package's types, made when first read."""

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        pkg, kind = self.__name__.split(".")
        full = "%s/%s/%s" % (pkg, kind, name)
        try:
            cls = getattr(self.__interfaces__, {"msg": "message", "srv": "service", "action": "action"}[kind])(full)
        except LookupError as e:
            raise AttributeError("module %r has no attribute %r (%s)" % (self.__name__, name, e)) from None
        setattr(self, name, cls)
        return cls


class Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds PKG, PKG.msg, PKG.srv and PKG.action for the ROS packages the gateway knows. It is the
    last finder on sys.meta_path: a real module of the same name comes first."""

    def __init__(self, interfaces):
        self.interfaces = interfaces

    def find_spec(self, fullname, path, target=None):
        parts = fullname.split(".")
        if len(parts) > 2 or (len(parts) == 2 and parts[1] not in KINDS):
            return None
        if not self.interfaces.is_package(parts[0]):
            return None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=len(parts) == 1)

    def create_module(self, spec):
        if "." in spec.name:
            module = _KindModule(spec.name)
            module.__interfaces__ = self.interfaces
            return module
        module = types.ModuleType(spec.name)
        module.__path__ = []
        return module

    def exec_module(self, module):
        pass


def install(interfaces):
    """Puts the finder last on sys.meta_path (once per run)."""
    for f in list(sys.meta_path):
        if isinstance(f, Finder):
            sys.meta_path.remove(f)
    finder = Finder(interfaces)
    sys.meta_path.append(finder)
    return finder
