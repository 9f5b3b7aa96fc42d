"""rclpy.signals for Python in the IDE page: Stop ends the program's worker; no handler to install."""

import enum


class SignalHandlerOptions(enum.Enum):
    NO = 0
    SIGINT = 1
    SIGTERM = 2
    ALL = 3


def install_signal_handlers(options=SignalHandlerOptions.ALL):
    pass


def get_current_signal_handlers_options():
    return SignalHandlerOptions.NO


def uninstall_signal_handlers():
    pass
