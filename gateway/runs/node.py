"""A ROS 2 node of the IDE's generator (``ide/generators/node.js``) as one file a run can start.

The node a student downloads is an ament_python package: the node's module imports
``PKG.rosgate_node``, which imports ``.rosgate_runtime``. A run's box shows it one file
(``program.py``), so here that file carries the two runtime modules, this gateway's own copies from
``ide/runtime/``, as the modules of a package ``rosgate_run`` (made at start, before the node's
imports run), and the node with its package import pointed there. Only a trusted run
(``--trusted-runs``: on the ROS graph, with the gateway's ROS installs) can be a node.
"""

from __future__ import annotations

import re
from pathlib import Path

KIND = 'ros2_node'
PACKAGE = 'rosgate_run'
MODULES = ('rosgate_runtime', 'rosgate_node')      # in import order
NODE_IMPORT = re.compile(r'^from\s+[A-Za-z_]\w*\.rosgate_node\s+import\s+\*', re.M)

LOADER = '''import sys as _sys, types as _types
_package = _types.ModuleType({package!r})
_package.__path__ = []
_sys.modules[{package!r}] = _package
for _name, _text in {modules!r}:
    _module = _types.ModuleType({package!r} + '.' + _name)
    _module.__package__ = {package!r}
    _sys.modules[_module.__name__] = _module
    setattr(_package, _name, _module)
    exec(compile(_text, _name + '.py', 'exec'), _module.__dict__)
'''


def node_program(source: str, runtime_dir: Path) -> str:
    """program.py for a run of the node ``source``; ValueError when it is not a node of the IDE's
    generator (no ``from PKG.rosgate_node import *``)."""
    if not NODE_IMPORT.search(source):
        raise ValueError('a ROS 2 node run takes the node the IDE generates (its module imports '
                         '"from PKG.rosgate_node import *")')
    modules = tuple((name, (runtime_dir / f'{name}.py').read_text()) for name in MODULES)
    node = NODE_IMPORT.sub(f'from {PACKAGE}.rosgate_node import *', source, count=1)
    return LOADER.format(package=PACKAGE, modules=modules) + '\n' + node


def node_arguments(ns: str) -> list[str]:
    """The node's arguments for a run in namespace ns (as ``ros2 run ... -r __ns:=NS``)."""
    return ['--ros-args', '-r', f'__ns:={ns}'] if ns else []
