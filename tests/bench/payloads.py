"""Sensor payloads: a 640x480 rgb8 Image and a 10k-point PointCloud2.

Each comes as the JSON publish frame a client sends (uint8[] as base64) and as
the cbor and cbor-raw frames a rosbridge server sends to such subscribers; the
harness preloads the latter into the ceiling server.
"""

from __future__ import annotations

import base64
import os
from dataclasses import dataclass

import cbor2
import numpy as np
import orjson

IMAGE_TYPE = "sensor_msgs/msg/Image"
CLOUD_TYPE = "sensor_msgs/msg/PointCloud2"


@dataclass(frozen=True)
class Payload:
    name: str
    type: str
    msg: dict  # rosbridge shape with uint8[] as bytes

    def publish_frame(self, topic: str) -> bytes:
        msg = dict(self.msg, data=base64.b64encode(self.msg["data"]).decode())
        return orjson.dumps({"op": "publish", "topic": topic, "msg": msg})

    def server_frame(self, topic: str, compression: str) -> bytes:
        """What a rosbridge server sends to a `compression` subscriber."""
        if compression == "cbor":
            return cbor2.dumps({"op": "publish", "topic": topic, "msg": self.msg})
        if compression == "cbor-raw":
            raw = {"secs": 0, "nsecs": 0, "bytes": self.cdr()}
            return cbor2.dumps({"op": "publish", "topic": topic, "msg": raw})
        raise ValueError(compression)

    def cdr(self) -> bytes:
        from rosbags.typesys import Stores, get_typestore

        store = get_typestore(Stores.ROS2_JAZZY)
        return bytes(store.serialize_cdr(_to_rosbags(store, self.type, self.msg), self.type))


def _to_rosbags(store, type_name: str, value):
    cls = store.types[type_name]
    fields = {}
    for name, (kind, spec) in zip(cls.__dataclass_fields__, _field_specs(store, type_name)):
        item = value[name]
        if kind == "msg":
            fields[name] = _to_rosbags(store, spec, item)
        elif kind == "msgs":
            fields[name] = [_to_rosbags(store, spec, v) for v in item]
        elif kind == "bytes":
            fields[name] = np.frombuffer(item, dtype=np.uint8)
        else:
            fields[name] = item
    return cls(**fields)


def _field_specs(store, type_name: str):
    """(kind, nested type) per field, from the typestore's definition."""
    _consts, definition = store.fielddefs[type_name]
    for _name, (node_type, desc) in definition:
        if node_type == 2:  # NAME: nested message
            yield "msg", desc
        elif node_type in (3, 4):  # ARRAY, SEQUENCE
            elem_type, elem = desc[0]
            if elem_type == 2:
                yield "msgs", elem
            elif elem[0] in ("uint8", "octet", "char"):
                yield "bytes", None
            else:
                yield "plain", None
        else:
            yield "plain", None


def _header(frame_id: str) -> dict:
    return {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame_id}


def image(width: int = 640, height: int = 480) -> Payload:
    msg = {
        "header": _header("camera"),
        "height": height,
        "width": width,
        "encoding": "rgb8",
        "is_bigendian": 0,
        "step": width * 3,
        "data": os.urandom(width * height * 3),
    }
    return Payload(f"image_{width}x{height}_rgb8", IMAGE_TYPE, msg)


def pointcloud(points: int = 10_000) -> Payload:
    fields = [
        {"name": name, "offset": 4 * i, "datatype": 7, "count": 1}  # 7: FLOAT32
        for i, name in enumerate(("x", "y", "z", "intensity"))
    ]
    cloud = np.random.default_rng(1).random((points, 4), dtype=np.float32)
    msg = {
        "header": _header("lidar"),
        "height": 1,
        "width": points,
        "fields": fields,
        "is_bigendian": False,
        "point_step": 16,
        "row_step": 16 * points,
        "data": cloud.tobytes(),
        "is_dense": True,
    }
    return Payload(f"pointcloud2_{points // 1000}k", CLOUD_TYPE, msg)
