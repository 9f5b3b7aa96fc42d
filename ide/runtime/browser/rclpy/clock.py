"""rclpy.clock and rclpy.time's clock types for Python in the IDE page: the system clock of the
student's machine (the gateway's ROS time is /rosapi/get_time)."""

import enum
import time as _time

from rclpy.duration import Duration


class ClockType(enum.IntEnum):
    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


class Clock:
    def __init__(self, *, clock_type=ClockType.SYSTEM_TIME):
        self._clock_type = clock_type

    @property
    def clock_type(self):
        return self._clock_type

    def __repr__(self):
        return "Clock(clock_type={0})".format(self.clock_type.name)

    def now(self):
        from rclpy.time import Time
        ns = _time.monotonic_ns() if self._clock_type == ClockType.STEADY_TIME else _time.time_ns()
        return Time(nanoseconds=ns, clock_type=self._clock_type)

    def sleep_for(self, rel_time):
        if isinstance(rel_time, Duration):
            rel_time = rel_time.nanoseconds / 1e9
        _time.sleep(max(0.0, rel_time))     # the page's sleep: the program's messages come in meanwhile
        return True

    def sleep_until(self, until):
        return self.sleep_for((until.nanoseconds - self.now().nanoseconds) / 1e9)


class ROSClock(Clock):
    def __init__(self):
        super().__init__(clock_type=ClockType.ROS_TIME)

    @property
    def ros_time_is_active(self):
        return False
