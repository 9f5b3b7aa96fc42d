"""rclpy (ROS 2 Jazzy's client library API) for Python in the IDE page.

A node here is the page's: what it publishes, subscribes, serves and calls goes through the
gateway on the page's own connection, under the gateway's rules, as any op of the page does
(rclpy/_engine.py). ``from std_msgs.msg import String`` and the like are made from the gateway's
type definitions (rosgate_interfaces.py). The ROS 2 tutorials' Python nodes run here unchanged,
and a program written here runs unchanged under rclpy on a ROS 2 machine.
"""

from rclpy import _engine
from rclpy.context import Context, default_context
from rclpy.parameter import Parameter  # noqa: F401 (rclpy.Parameter, as rclpy has it)
from rclpy.signals import SignalHandlerOptions  # noqa: F401
from rclpy.utilities import get_rmw_implementation_identifier, ok, remove_ros_args  # noqa: F401

_global_executor = None


def init(*, args=None, context=None, domain_id=None, signal_handler_options=None):
    """Starts the context; usable as ``with rclpy.init():`` (it shuts down at the end)."""
    context = default_context() if context is None else context
    context.init(args, domain_id=domain_id)
    _engine.engine()
    return context


def shutdown(*, context=None, uninstall_handlers=None):
    global _global_executor
    context = default_context() if context is None else context
    context.shutdown()
    if _global_executor is not None and context is default_context():
        _global_executor.shutdown()
        _global_executor = None


def try_shutdown(*, context=None, uninstall_handlers=None):
    context = default_context() if context is None else context
    if context.ok():
        shutdown(context=context)


def get_default_context(*, shutting_down=False):
    return default_context()


def get_global_executor():
    global _global_executor
    if _global_executor is None:
        from rclpy.executors import SingleThreadedExecutor
        _global_executor = SingleThreadedExecutor()
    return _global_executor


def create_node(node_name, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False,
                enable_logger_service=False):
    from rclpy.node import Node
    return Node(node_name, context=context, cli_args=cli_args, namespace=namespace,
                use_global_arguments=use_global_arguments, enable_rosout=enable_rosout,
                start_parameter_services=start_parameter_services, parameter_overrides=parameter_overrides,
                allow_undeclared_parameters=allow_undeclared_parameters,
                automatically_declare_parameters_from_overrides=automatically_declare_parameters_from_overrides,
                enable_logger_service=enable_logger_service)


def spin_once(node, *, executor=None, timeout_sec=None):
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)


def spin(node, executor=None):
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        while executor.context.ok():
            executor.spin_once()
    finally:
        executor.remove_node(node)


def spin_until_future_complete(node, future, executor=None, timeout_sec=None):
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec)
    finally:
        executor.remove_node(node)


__all__ = ["Context", "init", "shutdown", "try_shutdown", "ok", "spin", "spin_once", "spin_until_future_complete",
           "create_node", "get_global_executor", "get_default_context"]
