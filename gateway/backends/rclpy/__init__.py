"""The rclpy backend: the gateway as one node of a real ROS 2 (Jazzy) graph.

``backend`` (the node, its topics, services and actions), ``entities`` (its publishers, subscriptions
and served services, QoS in rclpy's terms), ``queries`` (what it answers from its type definitions
and the graph, and parameters), ``pump`` (the thread that waits on the
gateway's rcl entities and hands batches to the loop), ``cdr`` (a per-type CDR reader and writer),
``types`` (definitions and converters of the installed interface packages), ``graphtypes`` and
``rawtype`` (message types the install lacks, described by the graph, moved as CDR), ``build``
(service and action types the install lacks, built on first use), ``actions`` and ``params``. rclpy is imported when the backend starts, so importing this package works without ROS.
"""

from .backend import RclpyBackend

__all__ = ['RclpyBackend']
