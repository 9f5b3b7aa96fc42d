"""The embedded sim backend: an in-process ROS-like graph with demo nodes and simulated robots.

Rooms: ``backend`` (``SimBackend``, the backend contract over the graph), ``graph`` (nodes, topics,
services, actions, parameters), ``timers`` (every timer of one period on one loop callback),
``demo`` (the demo nodes: talker, fibonacci, ...), ``robots/`` (turtlesim, the rover, worlds,
stations and the fleet, and their flags).
"""

from .backend import SimBackend
from .graph import Graph, Node

__all__ = ['Graph', 'Node', 'SimBackend']
