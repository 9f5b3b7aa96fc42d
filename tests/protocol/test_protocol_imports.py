"""protocol/ is sans-I/O: it must not import tornado, rclpy or asyncio (nor the gateway)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / 'protocol'
FORBIDDEN = {'tornado', 'rclpy', 'asyncio', 'gateway'}


def imported_modules(source: str) -> set[str]:
    """Top-level names of every module an source file imports (anywhere, including inside functions)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split('.')[0])
        elif (isinstance(node, ast.Call) and isinstance(node.func, (ast.Name, ast.Attribute))
              and getattr(node.func, 'id', getattr(node.func, 'attr', '')) in ('import_module', '__import__')
              and node.args and isinstance(node.args[0], ast.Constant)):
            names.add(str(node.args[0].value).split('.')[0])
    return names


def test_scanner_sees_every_import_form():
    source = ('import asyncio\nfrom tornado.web import App\ndef f():\n    import rclpy.node\n'
              'import importlib\nimportlib.import_module("gateway.x")\nfrom . import codec\n')
    assert imported_modules(source) >= {'asyncio', 'tornado', 'rclpy', 'gateway'}
    assert 'codec' not in imported_modules(source)


def test_protocol_package_imports_no_io_framework():
    files = sorted(PACKAGE.rglob('*.py'))
    assert len(files) >= 6
    offenders = {str(p.relative_to(PACKAGE)): sorted(imported_modules(p.read_text()) & FORBIDDEN) for p in files}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_importing_protocol_loads_no_io_framework():
    code = ('import sys, protocol, protocol.convert, protocol.session; '
            f'print(sorted(m for m in {sorted(FORBIDDEN)!r} if m in sys.modules))')
    out = subprocess.run([sys.executable, '-c', code], cwd=PACKAGE.parent, capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == '[]'
