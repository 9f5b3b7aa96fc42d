"""rclpy.qos (Jazzy's names) for Python in the IDE page. The gateway's connection carries what
rosbridge can say of a profile: the depth (a subscription's queue_length, a publisher's
queue_size) and transient-local durability (a latched publisher); the rest is accepted and kept."""

import enum

from rclpy.duration import Duration


class HistoryPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class ReliabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class DurabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class LivelinessPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


# the older names
QoSHistoryPolicy, QoSReliabilityPolicy, QoSDurabilityPolicy, QoSLivelinessPolicy = (
    HistoryPolicy, ReliabilityPolicy, DurabilityPolicy, LivelinessPolicy)


class InvalidQoSProfileException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "Invalid QoSProfile", *args)


class QoSProfile:
    __slots__ = ("_history", "_depth", "_reliability", "_durability", "_lifespan", "_deadline",
                 "_liveliness", "_liveliness_lease_duration", "_avoid_ros_namespace_conventions")

    def __init__(self, **kwargs):
        if "history" not in kwargs and "depth" not in kwargs:
            raise InvalidQoSProfileException("History and/or depth settings are required.")
        self.history = kwargs.get("history", HistoryPolicy.KEEP_LAST)
        if self.history == HistoryPolicy.KEEP_LAST and "depth" not in kwargs:
            raise InvalidQoSProfileException("History set to KEEP_LAST without a depth setting.")
        self.depth = kwargs.get("depth", 0)
        self.reliability = kwargs.get("reliability", ReliabilityPolicy.RELIABLE)
        self.durability = kwargs.get("durability", DurabilityPolicy.VOLATILE)
        self.lifespan = kwargs.get("lifespan", Duration())
        self.deadline = kwargs.get("deadline", Duration())
        self.liveliness = kwargs.get("liveliness", LivelinessPolicy.SYSTEM_DEFAULT)
        self.liveliness_lease_duration = kwargs.get("liveliness_lease_duration", Duration())
        self.avoid_ros_namespace_conventions = kwargs.get("avoid_ros_namespace_conventions", False)

    history = property(lambda self: self._history, lambda self, v: setattr(self, "_history", HistoryPolicy(v)))
    reliability = property(lambda self: self._reliability,
                           lambda self, v: setattr(self, "_reliability", ReliabilityPolicy(v)))
    durability = property(lambda self: self._durability,
                          lambda self, v: setattr(self, "_durability", DurabilityPolicy(v)))
    liveliness = property(lambda self: self._liveliness,
                          lambda self, v: setattr(self, "_liveliness", LivelinessPolicy(v)))
    lifespan = property(lambda self: self._lifespan, lambda self, v: setattr(self, "_lifespan", v))
    deadline = property(lambda self: self._deadline, lambda self, v: setattr(self, "_deadline", v))
    liveliness_lease_duration = property(lambda self: self._liveliness_lease_duration,
                                         lambda self, v: setattr(self, "_liveliness_lease_duration", v))
    avoid_ros_namespace_conventions = property(lambda self: self._avoid_ros_namespace_conventions,
                                               lambda self, v: setattr(self, "_avoid_ros_namespace_conventions", v))

    @property
    def depth(self):
        return self._depth

    @depth.setter
    def depth(self, value):
        if not isinstance(value, int) or value < 0:
            raise ValueError("depth must be a non-negative integer")
        self._depth = value

    def __eq__(self, other):
        if not isinstance(other, QoSProfile):
            return False
        return all(getattr(self, s) == getattr(other, s) for s in self.__slots__)

    def __repr__(self):
        return "QoSProfile(history=%s, depth=%d, reliability=%s, durability=%s)" % (
            self.history.name, self.depth, self.reliability.name, self.durability.name)


qos_profile_system_default = QoSProfile(history=HistoryPolicy.SYSTEM_DEFAULT, depth=0,
                                        reliability=ReliabilityPolicy.SYSTEM_DEFAULT,
                                        durability=DurabilityPolicy.SYSTEM_DEFAULT)
qos_profile_sensor_data = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                                     reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_services_default = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10)
qos_profile_parameters = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000)
qos_profile_parameter_events = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000)
qos_profile_action_status_default = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                                               durability=DurabilityPolicy.TRANSIENT_LOCAL)


class QoSPresetProfiles(enum.Enum):
    SYSTEM_DEFAULT = qos_profile_system_default
    SENSOR_DATA = qos_profile_sensor_data
    SERVICES_DEFAULT = qos_profile_services_default
    PARAMETERS = qos_profile_parameters
    PARAMETER_EVENTS = qos_profile_parameter_events
    ACTION_STATUS_DEFAULT = qos_profile_action_status_default

    @classmethod
    def short_keys(cls):
        return [m.name.lower() for m in cls]

    @classmethod
    def get_from_short_key(cls, name):
        return cls[name.upper()].value


def profile(qos_profile):
    """A QoSProfile from what the Node methods take: a profile or a depth."""
    if isinstance(qos_profile, QoSProfile):
        return qos_profile
    if isinstance(qos_profile, int) and not isinstance(qos_profile, bool):
        return QoSProfile(depth=qos_profile)
    raise TypeError("Expected QoSProfile or int, but received {!r}".format(type(qos_profile)))
