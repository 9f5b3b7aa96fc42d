"""The embedded sim backend: an in-process ROS-like graph with demo nodes and simulated robots."""

from .backend import SimBackend
from .graph import Graph, Node

__all__ = ['Graph', 'Node', 'SimBackend']
