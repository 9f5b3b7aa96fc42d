"""rclpy.time (Jazzy's API) for Python in the IDE page."""

from rclpy.clock import ClockType
from rclpy.duration import Duration

S_TO_NS = 1000 * 1000 * 1000


class Time:
    def __init__(self, *, seconds=0, nanoseconds=0, clock_type=ClockType.SYSTEM_TIME):
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if total < 0:
            raise ValueError("Total nanoseconds value is too low to store in C time.")
        self._nanoseconds = total
        self._clock_type = clock_type

    @property
    def nanoseconds(self):
        return self._nanoseconds

    @property
    def clock_type(self):
        return self._clock_type

    def seconds_nanoseconds(self):
        return divmod(self.nanoseconds, S_TO_NS)

    def __repr__(self):
        return "Time(nanoseconds={0}, clock_type={1})".format(self.nanoseconds, self.clock_type.name)

    def __add__(self, other):
        if isinstance(other, Duration):
            return Time(nanoseconds=self.nanoseconds + other.nanoseconds, clock_type=self.clock_type)
        return NotImplemented

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, Time):
            if self.clock_type != other.clock_type:
                raise TypeError("Can't subtract times with different clock types")
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        if isinstance(other, Duration):
            return Time(nanoseconds=self.nanoseconds - other.nanoseconds, clock_type=self.clock_type)
        return NotImplemented

    def _compare(self, other):
        if not isinstance(other, Time):
            return NotImplemented
        if self.clock_type != other.clock_type:
            raise TypeError("Can't compare times with different clock types")
        return self.nanoseconds - other.nanoseconds

    def __eq__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d == 0

    def __ne__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d != 0

    def __lt__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d < 0

    def __le__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d <= 0

    def __gt__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d > 0

    def __ge__(self, other):
        d = self._compare(other)
        return d if d is NotImplemented else d >= 0

    def __hash__(self):
        return hash((self.nanoseconds, self.clock_type))

    def to_msg(self):
        from builtin_interfaces.msg import Time as TimeMsg
        sec, nanosec = self.seconds_nanoseconds()
        return TimeMsg(sec=sec, nanosec=nanosec)

    @classmethod
    def from_msg(cls, msg, clock_type=ClockType.ROS_TIME):
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)
