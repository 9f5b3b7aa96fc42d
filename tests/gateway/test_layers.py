"""gateway/ by role, imports pointing one way: web -> bridge -> rules -> backends (-> protocol); runs
(the run supervisor, its sandbox and cgroups) beside bridge, under web; lab (exercises, attempts,
grades, the roster) under web, above rules and auth; auth (tokens, sign-in sessions, LTI identities)
under rules, on the store alone; server and cli on top.

Every import of a gateway module is found (relative or absolute, at the top, inside a function or
under TYPE_CHECKING) and checked against what its role may use; the run-time imports (those at a
module's top) form no circle; and no gateway module is imported inside a function, the usual way
to hide a circle.
"""

from __future__ import annotations

import ast
from pathlib import Path

GATEWAY = Path(__file__).resolve().parents[2] / 'gateway'
MAY_USE = {   # role -> the roles its modules may import
    'web': {'web', 'bridge', 'media', 'twin', 'runs', 'lab', 'rules', 'auth', 'store', 'backends', 'settings'},
    'lab': {'lab', 'rules', 'auth', 'store', 'settings'},
    'runs': {'runs', 'rules', 'auth', 'store', 'backends', 'settings'},
    'bridge': {'bridge', 'media', 'rules', 'auth', 'store', 'backends', 'settings'},
    'media': {'media', 'rules', 'auth', 'store', 'backends', 'settings'},
    'twin': {'twin', 'rules', 'auth', 'store', 'backends', 'settings'},
    'rules': {'rules', 'auth', 'store', 'backends', 'settings'},
    'auth': {'auth', 'store', 'settings'},
    'store': {'store', 'settings'},
    'backends': {'backends'},
    'settings': {'settings'},
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(GATEWAY.parent).with_suffix('').parts)
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def package_of(path: Path) -> str:
    name = module_name(path)
    return name if path.name == '__init__.py' else name.rpartition('.')[0]


def role(module: str) -> str | None:
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[0] == 'gateway' else None


def gateway_imports(source: str, package: str) -> list[tuple[str, bool]]:
    """(module, at run time from the top of the file) for every gateway module the source imports;
    ``from . import x`` counts as importing the package and its module x."""
    tree = ast.parse(source)
    found: list[tuple[str, bool]] = []

    def visit(node, top: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = top
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                inner = False
            elif isinstance(child, ast.If) and 'TYPE_CHECKING' in ast.unparse(child.test):
                inner = None   # only for type checkers
            if isinstance(child, ast.Import):
                found.extend((a.name, inner) for a in child.names if a.name.split('.')[0] == 'gateway')
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split('.')[:len(package.split('.')) - child.level + 1]
                    module = '.'.join(base + ([child.module] if child.module else []))
                else:
                    module = child.module or ''
                if module.split('.')[0] == 'gateway':
                    found.append((module, inner))
                    found.extend((f'{module}.{a.name}', inner) for a in child.names)
            visit(child, inner)

    visit(tree, True)
    return found


def existing(module: str, modules: set[str]) -> str | None:
    while module and module not in modules:   # 'gateway.rules.policy.COOKIE' -> 'gateway.rules.policy'
        module = module.rpartition('.')[0]
    return module or None


def scan() -> dict[str, list[tuple[str, bool]]]:
    files = {module_name(p): p for p in GATEWAY.rglob('*.py')}
    out = {}
    for name, path in files.items():
        imports = gateway_imports(path.read_text(), package_of(path))
        out[name] = [(m, top) for m, top in ((existing(m, set(files)), top) for m, top in imports) if m]
    return out


def forbidden(graph) -> list[str]:
    bad = []
    for module, imports in graph.items():
        mine = role(module)
        for target, _ in imports:
            theirs = role(target)
            if mine in MAY_USE and theirs is not None and theirs not in MAY_USE[mine]:
                bad.append(f'{module} imports {target} ({mine} may not use {theirs})')
    return bad


def circles(graph) -> list[list[str]]:
    """Circles among run-time imports (a module's package __init__ runs before it)."""
    edges = {m: {t for t, top in imports if top and t != m} for m, imports in graph.items()}
    for m in graph:
        parent = m.rpartition('.')[0]
        if parent in graph and parent != m:
            edges[m].add(parent)
    found, state = [], {}

    def walk(node, stack):
        state[node] = 1
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1 and not (node.startswith(nxt + '.') or nxt.startswith(node + '.')):
                found.append(stack[stack.index(nxt):] + [nxt] if nxt in stack else [node, nxt])
            elif nxt not in state:
                walk(nxt, stack + [nxt])
        state[node] = 2

    for m in sorted(graph):
        if m not in state:
            walk(m, [m])
    return found


def test_the_roles_are_the_packages():
    entries = {p.name for p in GATEWAY.iterdir() if not p.name.startswith(('_', '.')) or p.name == '__init__.py'}
    assert entries <= {'__init__.py', 'cli.py', 'server.py', 'settings.py', 'bridge', 'rules', 'runs', 'web', 'store',
                       'backends', 'lab', 'media', 'twin', 'auth'}, entries
    for package in ('bridge', 'rules', 'runs', 'web', 'lab', 'media', 'twin', 'auth', 'backends', 'backends/sim',
                    'backends/rclpy'):
        assert ast.get_docstring(ast.parse((GATEWAY / package / '__init__.py').read_text())), package


def test_imports_point_one_way():
    assert forbidden(scan()) == []


def test_no_run_time_import_circle():
    assert circles(scan()) == []


def test_no_gateway_module_imported_inside_a_function():
    late = [f'{module} imports {target}' for module, imports in scan().items()
            for target, top in imports if top is False]
    assert late == []


def test_the_checks_see_what_they_forbid():
    """A forbidden import, a hidden one and a circle, each in the shapes the code uses."""
    backend = gateway_imports('def f():\n    from ...bridge import session\n', 'gateway.backends.sim')
    assert ('gateway.bridge.session', False) in backend
    graph = {'gateway.backends.sim.graph': backend, 'gateway.bridge.session': [],
             'gateway.rules.lease': gateway_imports('from ..web.runs import x\n', 'gateway.rules'),
             'gateway.web.runs': []}
    bad = forbidden(graph)
    assert any(b.startswith('gateway.backends.sim.graph imports gateway.bridge.session') for b in bad)
    assert any(b.startswith('gateway.rules.lease imports gateway.web.runs') for b in bad)
    up = {'gateway.runs.supervisor': gateway_imports('from ..web import api\n', 'gateway.runs'), 'gateway.web.api': []}
    assert 'gateway.runs.supervisor imports gateway.web.api (runs may not use web)' in forbidden(up)
    typed = gateway_imports('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .session import S\n',
                            'gateway.bridge')
    assert typed and all(top is None for _, top in typed)
    loop = {'gateway.web.api': [('gateway.web.login', True)], 'gateway.web.login': [('gateway.web.api', True)]}
    assert circles(loop)


def test_one_door_to_publish():
    """Only the gateway creates backend publishers (the shared ones behind its door, and its own
    announcements): nothing else in the process can publish past the rules."""
    outside = []
    for path in GATEWAY.rglob('*.py'):
        if 'backends' in path.relative_to(GATEWAY).parts or path == GATEWAY / 'bridge' / 'gateway.py':
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in ('create_publisher', '_handle'):
                outside.append(f'{path.relative_to(GATEWAY)}:{node.lineno} {node.attr}')
    assert outside == []


def holds_the_gateway(source: str) -> bool:
    """Whether a module is handed the whole Gateway: a parameter or attribute named ``gateway``
    (or ``gw``), ``.gateway`` read, or ``Gateway`` imported."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.arg) and node.arg in ('gateway', 'gw'):
            return True
        if isinstance(node, ast.Attribute) and node.attr == 'gateway':
            return True
        if isinstance(node, ast.ImportFrom) and any(a.name == 'Gateway' for a in node.names):
            return True
    return False


# Who still holds the Gateway (issue: none in rules/, lab/ (was exercises/), runs/; at most 5 in web/): the
# list only shrinks; a module that starts holding it again fails here.
STILL_HOLD = {
    'rules': set(),
    'auth': set(),
    'lab': set(),
    'runs': set(),
    'web': {'app.py', 'socket.py'},
    'media': set(),
    'twin': set(),
}


def test_who_holds_the_gateway():
    holders = {room: {p.name for p in sorted((GATEWAY / room).glob('*.py')) if holds_the_gateway(p.read_text())}
               for room in STILL_HOLD}
    grown = {room: sorted(found - STILL_HOLD[room]) for room, found in holders.items() if found - STILL_HOLD[room]}
    assert grown == {}, f'newly handed the whole Gateway (give them the few interfaces they use): {grown}'
    gone = {room: sorted(STILL_HOLD[room] - found) for room, found in holders.items() if STILL_HOLD[room] - found}
    assert gone == {}, f'no longer hold it: take them off STILL_HOLD {gone}'
    assert holds_the_gateway('class C:\n    def __init__(self, gateway):\n        self.gateway = gateway\n')
    assert holds_the_gateway('def f(x):\n    return x.gateway.store\n')
    assert not holds_the_gateway('def f(topics, store):\n    return topics.topic_type(store)\n')


# web/ is HTTP only (issue 52): every class in it is one of tornado's handlers, applications or
# websocket protocols (by its bases, followed through web/), or a port a handler is given (a
# typing.Protocol); no module keeps data (sqlalchemy) or follows the gateway's events (a
# rules.hooks.Hook): those live in their rooms (media/, twin/, ...), the routes over them here.
HTTP_BASES = {'tornado.web.RequestHandler', 'tornado.web.Application', 'tornado.web.StaticFileHandler',
              'tornado.web.RedirectHandler', 'tornado.websocket.WebSocketHandler',
              'tornado.websocket.WebSocketProtocol13', 'typing.Protocol'}
WEB_ALSO = {   # the other classes web/ keeps, each for its reason: the list only shrinks
    'language.py': {'Texts'},   # the login and LTI pages' words in the reader's language (Accept-Language)
    'logs.py': {'Scrub'},       # a logging filter: tokens and forged lines kept out of what the process logs
    'fastio.py': {'Connection', '_Listener', '_Protocol'},   # the websocket's frames on picows: transport
    'lti.py': {'Lti'},          # the LTI routes' shared state (the policy, the words, the examples folder)
}


def web_faults(sources: dict[str, str]) -> tuple[list[str], dict[str, set[str]]]:
    """(what is not HTTP in web/, the classes let through by name) for web/'s modules by file name."""
    trees = {name: ast.parse(text) for name, text in sources.items()}
    classes, imported = {}, {}
    for name, tree in trees.items():
        classes[name] = {n.name: n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
        imported[name] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for a in node.names:
                    if node.level == 1 and node.module:   # from .api import Handler: web/'s own
                        imported[name][a.asname or a.name] = ('web', f'{node.module}.py', a.name)
                    elif not node.level:
                        imported[name][a.asname or a.name] = ('outside', f'{node.module}.{a.name}', '')

    def http(module: str, base: ast.expr, seen: frozenset = frozenset()) -> bool:
        dotted = ast.unparse(base)
        if dotted in HTTP_BASES:
            return True
        found = imported[module].get(dotted)
        if found is not None and found[0] == 'outside':
            return found[1] in HTTP_BASES
        place = (found[1], found[2]) if found is not None else (module, dotted)
        node = classes.get(place[0], {}).get(place[1])
        if node is None or place in seen:
            return False
        return bool(node.bases) and all(http(place[0], b, seen | {place}) for b in node.bases)

    faults, named = [], {}
    for name, tree in sorted(trees.items()):
        for node in ast.walk(tree):
            modules = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                       [node.module or ''] if isinstance(node, ast.ImportFrom) and not node.level else [])
            faults += [f'web/{name} imports {m}: a store is a room\'s' for m in modules
                       if m.split('.')[0] == 'sqlalchemy']
        for cls in classes[name].values():
            bases = [ast.unparse(b) for b in cls.bases]
            if any(b.split('.')[-1] == 'Hook' for b in bases):
                faults.append(f'web/{name}: {cls.name} is a Hook: what follows the gateway\'s events is a room\'s')
            elif cls.bases and all(http(name, b) for b in cls.bases):
                continue
            elif cls.name in WEB_ALSO.get(name, ()):
                named.setdefault(name, set()).add(cls.name)
            else:
                faults.append(f'web/{name}: {cls.name}({", ".join(bases)}) is no handler, application or '
                              'websocket protocol: move it to its room')
    return faults, named


def test_web_is_http_only():
    faults, named = web_faults({p.name: p.read_text() for p in sorted((GATEWAY / 'web').glob('*.py'))})
    assert faults == []
    stale = {f: sorted(c - named.get(f, set())) for f, c in WEB_ALSO.items() if c - named.get(f, set())}
    assert stale == {}, f'no longer in web/ (or now HTTP): take them off WEB_ALSO {stale}'
    # the check itself, on planted modules: a store, a hook, a domain class; handlers through web/ pass
    planted, _ = web_faults({
        'api.py': 'import tornado.web\nfrom typing import Protocol\n'
                  'class Handler(tornado.web.RequestHandler): pass\nclass Port(Protocol): pass\n',
        'app.py': 'from tornado.web import Application\nclass App(Application): pass\n',
        'notes.py': 'import sqlalchemy as sa\nfrom sqlalchemy.orm import Session\nfrom ..rules.hooks import Hook\n'
                    'from .api import Handler\n'
                    'class _Base(Handler): pass\nclass NotesHandler(_Base): pass\n'
                    'class Keeper(Hook): pass\nclass Cache: pass\nclass Mixed(Handler, Cache): pass\n',
        'lti.py': 'class Lti: pass\nclass Later: pass\n'})
    assert sorted(planted) == sorted([
        "web/notes.py imports sqlalchemy: a store is a room's",
        "web/notes.py imports sqlalchemy.orm: a store is a room's",
        "web/notes.py: Keeper is a Hook: what follows the gateway's events is a room's",
        'web/notes.py: Cache() is no handler, application or websocket protocol: move it to its room',
        'web/notes.py: Mixed(Handler, Cache) is no handler, application or websocket protocol: move it to its room',
        'web/lti.py: Later() is no handler, application or websocket protocol: move it to its room'])
