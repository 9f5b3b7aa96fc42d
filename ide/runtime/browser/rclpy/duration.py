"""rclpy.duration (Jazzy's API) for Python in the IDE page."""

S_TO_NS = 1000 * 1000 * 1000


class Duration:
    def __init__(self, *, seconds=0, nanoseconds=0):
        total = int(seconds * S_TO_NS) + int(nanoseconds)
        if total < -2 ** 63 or total >= 2 ** 63:
            raise OverflowError("Total nanoseconds value is too large to store in C duration.")
        self._nanoseconds = total

    @property
    def nanoseconds(self):
        return self._nanoseconds

    def __repr__(self):
        return "Duration(nanoseconds={0})".format(self.nanoseconds)

    def __str__(self):
        return "{0} nanoseconds".format(self.nanoseconds)

    def __eq__(self, other):
        if isinstance(other, Duration):
            return self.nanoseconds == other.nanoseconds
        return NotImplemented

    def __ne__(self, other):
        return not self.__eq__(other)

    def __lt__(self, other):
        if isinstance(other, Duration):
            return self.nanoseconds < other.nanoseconds
        return NotImplemented

    def __le__(self, other):
        return self < other or self == other

    def __gt__(self, other):
        if isinstance(other, Duration):
            return self.nanoseconds > other.nanoseconds
        return NotImplemented

    def __ge__(self, other):
        return self > other or self == other

    def __hash__(self):
        return hash(self.nanoseconds)

    def __add__(self, other):
        if isinstance(other, Duration):
            return Duration(nanoseconds=self.nanoseconds + other.nanoseconds)
        return NotImplemented

    def __sub__(self, other):
        if isinstance(other, Duration):
            return Duration(nanoseconds=self.nanoseconds - other.nanoseconds)
        return NotImplemented

    def __mul__(self, other):
        if isinstance(other, (int, float)):
            return Duration(nanoseconds=int(self.nanoseconds * other))
        return NotImplemented

    __rmul__ = __mul__

    def to_msg(self):
        from builtin_interfaces.msg import Duration as DurationMsg
        sec, nanosec = divmod(self.nanoseconds, S_TO_NS)
        return DurationMsg(sec=sec, nanosec=nanosec)

    @classmethod
    def from_msg(cls, msg):
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec)

    def get_c_duration(self):
        return self
