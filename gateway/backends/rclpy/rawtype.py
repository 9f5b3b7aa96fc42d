"""A message type support made at run time from a type description: CDR bytes in and out, no build.

For a type the install lacks, the gateway has its description from the graph (``graphtypes``) but
no generated package. ``RawType`` puts together, with ctypes, a ``rosidl_message_type_support_t``
with the identifier of ``rosidl_typesupport_fastrtps_c`` whose (de)serialize callbacks never run:
the backend only takes and publishes serialized messages (``take_message(cls, True)``,
``publish_raw``), which rcl hands to rmw_fastrtps as CDR buffers it copies as they are. What rmw
does read from it: the DDS type name (``pkg::msg::dds_::Name_``), the type hash (the robot's, from
the graph, so no endpoint reports a mismatch), the type description (rcl registers it in the
node's type cache) and an introspection type support made from the description (names, kinds and
bounds, no offsets), from which rmw_fastrtps registers the DDS type object.

Measured (PyPI Jazzy wheels, Fast DDS, 2 cores): making one took 3-150 ms, and a process that
lacked the package had the robot's first message 0.7-0.8 s after it started, discovery included.
The alternatives: ``rcl_dynamic_message_type_support_handle_init`` works for subscriptions only
(rmw_fastrtps_cpp rejects it for a publisher: "Type support not from this implementation") and
crashes on ordinary descriptions (a bool default of 'True'); generating and building the package
takes 12-58 s and a C compiler.

It relies on C struct layouts of Jazzy (rosidl_runtime_c 4.6, rosidl_typesupport_fastrtps_c 3.6,
rosidl_typesupport_introspection_c 4.6, rclpy 7.1 reading ``_TYPE_SUPPORT`` from the metaclass);
``self_test`` round-trips an installed type through one before the first use and says so plainly
when the layouts do not match. Libraries are loaded on first use: importing this works without ROS.
"""

from __future__ import annotations

import ctypes
import os
import sys
from functools import cache

# rosidl_message_type_support_t
class MessageTypeSupport(ctypes.Structure):
    _fields_ = [('typesupport_identifier', ctypes.c_char_p), ('data', ctypes.c_void_p),
                ('func', ctypes.c_void_p), ('get_type_hash_func', ctypes.c_void_p),
                ('get_type_description_func', ctypes.c_void_p),
                ('get_type_description_sources_func', ctypes.c_void_p)]


class TypeHash(ctypes.Structure):           # rosidl_type_hash_t
    _fields_ = [('version', ctypes.c_uint8), ('value', ctypes.c_uint8 * 32)]


_SERIALIZE = ctypes.CFUNCTYPE(ctypes.c_bool, ctypes.c_void_p, ctypes.c_void_p)
_SIZE = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p)
_MAX_SIZE = ctypes.CFUNCTYPE(ctypes.c_size_t, ctypes.POINTER(ctypes.c_char))
_TS_FN = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p)
_HANDLE_FN = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_char_p)
# the message capsules rclpy checks for; a raw take or publish never calls them
_CREATE = ctypes.CFUNCTYPE(ctypes.c_void_p)
_DESTROY = ctypes.CFUNCTYPE(None, ctypes.c_void_p)
_FROM_PY = ctypes.PYFUNCTYPE(ctypes.c_bool, ctypes.py_object, ctypes.c_void_p)
_TO_PY = ctypes.PYFUNCTYPE(ctypes.py_object, ctypes.c_void_p)


class FastrtpsCallbacks(ctypes.Structure):   # message_type_support_callbacks_t
    _fields_ = [('message_namespace_', ctypes.c_char_p), ('message_name_', ctypes.c_char_p),
                ('cdr_serialize', _SERIALIZE), ('cdr_deserialize', _SERIALIZE),
                ('get_serialized_size', _SIZE), ('max_serialized_size', _MAX_SIZE),
                ('key_callbacks', ctypes.c_void_p)]


class _EmptySources(ctypes.Structure):       # rosidl_runtime_c__type_description__TypeSource__Sequence
    _fields_ = [('data', ctypes.c_void_p), ('size', ctypes.c_size_t), ('capacity', ctypes.c_size_t)]


class IntroMember(ctypes.Structure):        # rosidl_typesupport_introspection_c__MessageMember
    _fields_ = [('name_', ctypes.c_char_p), ('type_id_', ctypes.c_uint8),
                ('string_upper_bound_', ctypes.c_size_t), ('members_', ctypes.c_void_p),
                ('is_key_', ctypes.c_bool), ('is_array_', ctypes.c_bool), ('array_size_', ctypes.c_size_t),
                ('is_upper_bound_', ctypes.c_bool), ('offset_', ctypes.c_uint32),
                ('default_value_', ctypes.c_void_p), ('size_function', ctypes.c_void_p),
                ('get_const_function', ctypes.c_void_p), ('get_function', ctypes.c_void_p),
                ('fetch_function', ctypes.c_void_p), ('assign_function', ctypes.c_void_p),
                ('resize_function', ctypes.c_void_p)]


class IntroMembers(ctypes.Structure):       # rosidl_typesupport_introspection_c__MessageMembers
    _fields_ = [('message_namespace_', ctypes.c_char_p), ('message_name_', ctypes.c_char_p),
                ('member_count_', ctypes.c_uint32), ('size_of_', ctypes.c_size_t),
                ('has_any_key_member_', ctypes.c_bool), ('members_', ctypes.POINTER(IntroMember)),
                ('init_function', ctypes.c_void_p), ('fini_function', ctypes.c_void_p)]


# type_description_interfaces/msg/FieldType base ids -> introspection ROS_TYPE ids
_INTRO_IDS = {1: 18, 2: 9, 3: 8, 4: 11, 5: 10, 6: 13, 7: 12, 8: 15, 9: 14, 10: 1, 11: 2, 12: 3,
              13: 4, 14: 5, 15: 6, 16: 7, 17: 16, 18: 17, 19: 16, 20: 17, 21: 16, 22: 17}


class _Py:
    """The CPython capsule API through ctypes."""

    def __init__(self):
        api = ctypes.pythonapi
        api.PyCapsule_GetPointer.restype = ctypes.c_void_p
        api.PyCapsule_GetPointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
        api.PyCapsule_GetName.restype = ctypes.c_char_p
        api.PyCapsule_GetName.argtypes = [ctypes.py_object]
        api.PyCapsule_New.restype = ctypes.py_object
        api.PyCapsule_New.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p]
        self.api = api

    def pointer(self, capsule) -> int:
        return self.api.PyCapsule_GetPointer(capsule, self.api.PyCapsule_GetName(capsule))

    def capsule(self, address: int, name: bytes | None):
        return self.api.PyCapsule_New(address, name, None)


@cache
def _runtime():
    """(capsule API, librosidl_runtime_c): loaded once, on first use."""
    for d in [*os.environ.get('LD_LIBRARY_PATH', '').split(os.pathsep), os.path.join(sys.prefix, 'lib')]:
        path = os.path.join(d, 'librosidl_runtime_c.so')
        if d and os.path.exists(path):
            return _Py(), ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
    return _Py(), ctypes.CDLL('librosidl_runtime_c.so', mode=ctypes.RTLD_GLOBAL)


def c_message(py_msg) -> tuple[int, tuple]:
    """A generated Python message as its C struct: (address, what keeps it alive). Uses the
    class's own capsules, as rclpy does (convert through PYFUNCTYPE: it needs the GIL)."""
    py, _ = _runtime()
    meta = type(py_msg).__class__
    if meta._CREATE_ROS_MESSAGE is None:
        meta.__import_type_support__()
    create = ctypes.CFUNCTYPE(ctypes.c_void_p)(py.pointer(meta._CREATE_ROS_MESSAGE))
    convert = _FROM_PY(py.pointer(meta._CONVERT_FROM_PY))
    address = create()
    if not address or not convert(py_msg, address):
        raise RuntimeError(f'cannot convert a {type(py_msg).__name__} to C')
    return address, (create, convert)


def introspection(description, keep: list) -> dict[str, MessageTypeSupport]:
    """Introspection (C) type supports for every type of a TypeDescription: names, kinds and
    bounds only (no offsets, no accessors: nothing may read a message through them)."""
    _, runtime = _runtime()
    handle = ctypes.cast(runtime.get_message_typesupport_handle_function, ctypes.c_void_p).value
    types = {t.type_name: t for t in [description.type_description, *description.referenced_type_descriptions]}
    out = {name: MessageTypeSupport(b'rosidl_typesupport_introspection_c', None, handle) for name in types}
    keep.append(out)        # allocated first: members point at each other
    for name, t in types.items():
        pkg, kind, short = name.split('/')
        members = (IntroMember * max(1, len(t.fields)))()
        for m, f in zip(members, t.fields):
            base, shape = f.type.type_id % 48, f.type.type_id // 48
            m.name_ = f.name.encode()
            m.type_id_ = _INTRO_IDS[base]
            m.string_upper_bound_ = f.type.string_capacity
            m.is_array_ = shape != 0
            m.array_size_ = f.type.capacity
            m.is_upper_bound_ = shape == 2
            if base == 1:
                nested = out.get(f.type.nested_type_name)
                if nested is None:
                    raise RuntimeError(f'{name}.{f.name}: {f.type.nested_type_name} is not described')
                m.members_ = ctypes.addressof(nested)
            keep.append(m.name_)
        mm = IntroMembers(f'{pkg}__{kind}'.encode(), short.encode(), len(t.fields), 0, False,
                          ctypes.cast(members, ctypes.POINTER(IntroMember)), None, None)
        keep.extend((members, mm))
        out[name].data = ctypes.addressof(mm)
    return out


def _never(msg, cdr) -> bool:
    return False        # only serialized messages go through: rmw copies their bytes itself


def _unbounded(bounds) -> int:
    bounds[0] = b'\x00'   # ROSIDL_TYPESUPPORT_FASTRTPS_UNBOUNDED_TYPE
    return 0


class RawType:
    """A CDR-only message type support for one described type. ``cls`` stands where rclpy wants a
    message class (``_rclpy.Subscription``, ``node.create_publisher``); use it with raw takes and
    ``publish(bytes)`` only: it makes no message objects (``raw_only``)."""

    def __init__(self, description, type_hash: str):
        """description: a type_description_interfaces/msg/TypeDescription; type_hash: 'RIHS01_<hex>'."""
        py, _ = _runtime()
        self.type = name = description.type_description.type_name            # pkg/msg/Name
        pkg, kind, short = name.split('/')
        self._c_desc, self._keep = c_message(description)
        self._sources = _EmptySources()
        self.hash = TypeHash()
        self.hash.version = int(type_hash[4:6])
        self.hash.value[:] = bytes.fromhex(type_hash[7:])
        self._cbs = FastrtpsCallbacks(f'{pkg}::{kind}'.encode(), short.encode(), _SERIALIZE(_never),
                                      _SERIALIZE(_never), _SIZE(lambda m: 0), _MAX_SIZE(_unbounded), None)
        self._fns = (_TS_FN(lambda ts: ctypes.addressof(self.hash)),
                     _TS_FN(lambda ts: self._c_desc),
                     _TS_FN(lambda ts: ctypes.addressof(self._sources)))
        self._keep_intro: list = []
        self._intro = introspection(description, self._keep_intro)[name]

        def handle(ts, identifier):     # get_message_typesupport_handle, for both identifiers
            if identifier == b'rosidl_typesupport_fastrtps_c':
                return ctypes.addressof(self.ts)
            if identifier == b'rosidl_typesupport_introspection_c':
                return ctypes.addressof(self._intro)
            return None
        self._handle = _HANDLE_FN(handle)
        self.ts = MessageTypeSupport(
            b'rosidl_typesupport_fastrtps_c', ctypes.addressof(self._cbs),
            ctypes.cast(self._handle, ctypes.c_void_p).value,
            *(ctypes.cast(f, ctypes.c_void_p).value for f in self._fns))
        # rclpy checks these exist; none runs for a raw take or publish (each fails cleanly if it did)
        self._dummies = (_CREATE(lambda: None), _DESTROY(lambda p: None),
                         _FROM_PY(lambda m, p: False), _TO_PY(lambda p: None))
        create, destroy, from_py, to_py = (py.capsule(ctypes.cast(f, ctypes.c_void_p).value, None)
                                           for f in self._dummies)
        meta = type('RawTypeMeta', (type,), {
            '_TYPE_SUPPORT': py.capsule(ctypes.addressof(self.ts), b'rosidl_message_type_support_t'),
            '_CREATE_ROS_MESSAGE': create, '_DESTROY_ROS_MESSAGE': destroy,
            '_CONVERT_FROM_PY': from_py, '_CONVERT_TO_PY': to_py,
            '__import_type_support__': classmethod(lambda cls: None)})
        self.cls = meta(short, (), {'raw_only': True, 'raw_type': self, '__slots__': ()})

    @property
    def hash_string(self) -> str:
        return 'RIHS%02d_%s' % (self.hash.version, bytes(self.hash.value).hex())


def type_hash(cls) -> str:
    """'RIHS01_<hex>' of a message class's type support (a generated class or a RawType's)."""
    py, _ = _runtime()
    meta = cls.__class__
    if meta._TYPE_SUPPORT is None:
        meta.__import_type_support__()
    ts = MessageTypeSupport.from_address(py.pointer(meta._TYPE_SUPPORT))
    get = ctypes.CFUNCTYPE(ctypes.POINTER(TypeHash), ctypes.c_void_p)(ts.get_type_hash_func)
    h = get(ctypes.addressof(ts)).contents
    return 'RIHS%02d_%s' % (h.version, bytes(h.value).hex())


def is_raw(cls) -> bool:
    """Whether cls is a RawType's class (no message objects: CDR only)."""
    return getattr(cls, 'raw_only', False) is True
