"""rclpy.logging for Python in the IDE page: rclpy's console format, into the page's console
(INFO and DEBUG as the program's output, WARN and above as its errors)."""

import enum
import time

import _rosgate_js as _js


class LoggingSeverity(enum.IntEnum):
    UNSET = 0
    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


_levels = {}               # logger name -> severity set on it
_default_level = LoggingSeverity.INFO


def _emit(severity, name, message):
    ns = time.time_ns()
    text = "[%s] [%d.%09d] [%s]: %s" % (severity.name, ns // 10 ** 9, ns % 10 ** 9, name, message)
    _js.log(text, "info" if severity < LoggingSeverity.WARN else "error")


class RcutilsLogger:
    def __init__(self, name=""):
        self.name = name
        self._once = set()
        self._skipped = set()
        self._last = {}

    def get_child(self, name):
        if not name:
            raise ValueError("Child logger name must not be empty.")
        return RcutilsLogger("%s.%s" % (self.name, name) if self.name else name)

    def set_level(self, level):
        _levels[self.name] = LoggingSeverity(level)
        return True

    def get_effective_level(self):
        name = self.name
        while True:
            if name in _levels:
                return _levels[name]
            if "." not in name:
                return _default_level
            name = name.rsplit(".", 1)[0]

    def is_enabled_for(self, severity):
        return LoggingSeverity(severity) >= self.get_effective_level()

    def log(self, message, severity, **kwargs):
        severity = LoggingSeverity(severity)
        if not self.is_enabled_for(severity):
            return False
        where = kwargs.get("name", self.name)
        key = (severity, str(message))
        if kwargs.get("once"):
            if key in self._once:
                return False
            self._once.add(key)
        if kwargs.get("skip_first") and key not in self._skipped:
            self._skipped.add(key)
            return False
        every = kwargs.get("throttle_duration_sec")
        if every:
            now = time.monotonic()
            if now - self._last.get(key, -1e18) < float(every):
                return False
            self._last[key] = now
        _emit(severity, where, message)
        return True

    def debug(self, message, **kwargs):
        return self.log(message, LoggingSeverity.DEBUG, **kwargs)

    def info(self, message, **kwargs):
        return self.log(message, LoggingSeverity.INFO, **kwargs)

    def warning(self, message, **kwargs):
        return self.log(message, LoggingSeverity.WARN, **kwargs)

    warn = warning

    def error(self, message, **kwargs):
        return self.log(message, LoggingSeverity.ERROR, **kwargs)

    def fatal(self, message, **kwargs):
        return self.log(message, LoggingSeverity.FATAL, **kwargs)


def get_logger(name):
    if not name:
        raise ValueError("Logger name must not be empty.")
    return RcutilsLogger(name)


def set_logger_level(name, level, detailed_error=False):
    _levels[name] = LoggingSeverity(level)


def get_logger_effective_level(name):
    return RcutilsLogger(name).get_effective_level()


def initialize():
    pass


def shutdown():
    pass
