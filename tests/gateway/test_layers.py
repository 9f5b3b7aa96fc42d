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
    # (a folder left with only __pycache__ by a move, in a working copy, is no package)
    entries = {p.name for p in GATEWAY.iterdir() if (not p.name.startswith(('_', '.')) or p.name == '__init__.py')
               and (p.is_file() or any(p.glob('*.py')))}
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


# --- nothing wired after construction ---------------------------------------------------------------

WIRED_ROOMS = ('rules', 'runs', 'exercises', 'lab', 'auth', 'media', 'twin', 'web', 'store', 'bridge')
REGISTERS = {'append', 'add', 'on', 'reader', 'insert', 'extend', 'setdefault', 'register', 'subscribe_to'}
# (file, the line's text): assignments after construction that are a part's own state, not wiring
WIRED_ALLOWED = {
    # the xacro library patched in the child process that expands a robot description (no part of ours)
    ('twin/xacro_child.py', 'substitution_args._eval_find = find'),
    ('twin/xacro_child.py', "substitution_args._eval_dict['find'] = find"),
    ('twin/xacro_child.py', 'xacro.open = guarded_open          # what xacro.parse and xacro.load_yaml open files with'),
    # state of a run or a subscription kept by the part that made it
    ('runs/supervisor.py', 'run.reason = reason'),
    ('bridge/fanout.py', 'sub.pending = pending'),
    # the handler hangs the run's recording on it (to go: the run manager given the recorder, plan-52 C3)
    ('web/runs.py', 'run.recorder = finish'),
}


def _root(node: ast.AST) -> ast.AST:
    while isinstance(node, (ast.Attribute, ast.Subscript)):
        node = node.value
    return node


def _own(node: ast.AST) -> bool:
    """``self.x`` or ``self.x[k]``: a part's own attribute (``self.x.y``: another part's)."""
    if isinstance(node, ast.Subscript):
        node = node.value
    return isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls')


def _callables(fn: ast.AST) -> set[str]:
    """Names a function binds to functions or lambdas of its own (``def finish``, ``f = lambda``)."""
    found = set()
    for node in ast.walk(fn):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node is not fn:
            found.add(node.name)
        elif isinstance(node, ast.Assign) and isinstance(node.value, ast.Lambda):
            found.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return found


def _built(fn: ast.AST) -> set[str]:
    """Names a function binds to what it builds itself (``Run(...)``, ``{}``): finishing those is
    construction, not wiring."""
    found = set()
    for node in ast.walk(fn):
        if isinstance(node, ast.Assign):
            v = node.value
            func = v.func if isinstance(v, ast.Call) else None
            name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ''
            if (isinstance(v, (ast.Dict, ast.List, ast.Set, ast.DictComp, ast.ListComp, ast.SetComp))
                    or name[:1].isupper() or name in ('dict', 'list', 'set')):
                found.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return found


def _params(fn: ast.AST) -> set[str]:
    a = fn.args
    return {x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)} - {'self', 'cls'}


def _functions(tree: ast.AST):
    """Every function with the method names of its class (none for a module's function)."""
    def visit(node, methods):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                yield from visit(child, {f.name for f in child.body
                                         if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))})
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield child, methods
                yield from visit(child, methods)
            else:
                yield from visit(child, methods)
    yield from visit(tree, set())


def wired_after_construction(source: str) -> list[tuple[int, str]]:
    """Where a part is wired by assignment after it was built: ``x.attr = v`` or ``x.attr[k] = v``
    (x not ``self``, nor something this function built) with v a lambda, a function of its own, a
    bound method (``self.tick``; ``stations.lost_elsewhere`` into a part it was handed), or a part
    it was handed under the attribute's name (``stations.fleet = fleet``); and ``x.y.append(cb)``
    (``add``, ``on``, ``reader`` ...) of such a callable on another part. A part is given what it
    uses in its constructor (or a ``start(...)`` that takes it), and hears events by ``rules.hooks``."""
    lines = source.splitlines()
    found = []
    for fn, methods in _functions(ast.parse(source)):
        made, params, built = _callables(fn), _params(fn), _built(fn)

        def callable_value(v, into=None):
            if isinstance(v, ast.Lambda) or (isinstance(v, ast.Name) and v.id in made):
                return True
            if isinstance(v, ast.Attribute) and isinstance(v.value, ast.Name):
                if v.value.id == 'self':
                    return v.attr in methods
                return v.value.id in params and v.value.id != into and (into is None or into in params)
            return False

        for node in ast.walk(fn):
            if isinstance(node, ast.Assign):
                for target in node.targets:
                    pairs = (zip(target.elts, node.value.elts) if isinstance(target, ast.Tuple)
                             and isinstance(node.value, ast.Tuple) else [(target, node.value)])
                    for t, v in pairs:
                        root = _root(t)
                        if (not isinstance(t, (ast.Attribute, ast.Subscript)) or _own(t)
                                or not isinstance(root, ast.Name)):
                            continue
                        handed = (isinstance(t, ast.Attribute) and isinstance(v, ast.Name) and v.id in params
                                  and v.id == t.attr and root.id not in built)
                        if handed or callable_value(v, root.id):
                            found.append((node.lineno, lines[node.lineno - 1].strip()))
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr in REGISTERS and not _own(node.func.value)
                  and (not isinstance(node.func.value, ast.Name) or node.func.value.id in params)):
                if any(callable_value(a) for a in node.args):
                    found.append((node.lineno, lines[node.lineno - 1].strip()))
    return sorted(set(found))


def test_nothing_wired_after_construction():
    """Each part is given what it uses when it is built (``server.start``, ``rules.compose``), and
    hears events through ``rules.hooks`` alone: no callback slot filled, no part handed in, no
    listener appended once it exists (issue 52)."""
    files = [GATEWAY / 'server.py'] + [p for room in WIRED_ROOMS for p in sorted((GATEWAY / room).rglob('*.py'))]
    wired = [f'{p.relative_to(GATEWAY)}:{line} {text}' for p in files
             for line, text in wired_after_construction(p.read_text())
             if (str(p.relative_to(GATEWAY)), text) not in WIRED_ALLOWED]
    assert wired == [], 'wired after construction (give it to the constructor):\n' + '\n'.join(wired)


def test_the_wiring_check_sees_what_it_forbids():
    planted = [
        'def compose(store):\n    sessions = Sessions(store)\n    def signed_out(key):\n        pass\n'
        '    sessions.on_revoked = signed_out\n',                              # a callback slot filled
        'class Slots:\n    def __init__(self, timetable):\n        timetable.changed = self.tick\n'
        '    def tick(self):\n        pass\n',                                       # a bound method
        'def join(fleet, stations):\n    stations.fleet = fleet\n',             # a part handed in
        'def join(fleet, stations):\n    fleet.lost["claim"] = stations.lost_elsewhere\n',
        'def join(fleet, lease):\n    fleet.changed["stop"] = lambda g, old, new: lease.stop(g)\n',
        'def join(fleet, lease):\n    fleet.cut.append(lease.cut_off)\n',      # a listener appended
        'def join(fleet, stations):\n    fleet.on("hold", lambda e: stations.refresh())\n',
        'class Twin:\n    def start(self):\n        self.history.listeners.append(self.on_point)\n'
        '    def on_point(self, *a):\n        pass\n',
        'def record(run, recordings):\n    def finish():\n        return recordings.stop()\n    run.recorder = finish\n',
        'def f(a, b):\n    a.b, a.y = b, 1\n',
    ]
    for source in planted:
        assert wired_after_construction(source), source
    fine = [
        'class A:\n    def __init__(self, fleet):\n        self.fleet = fleet\n        self.tick = lambda: 1\n',
        'def check(self, now):\n    for o in self.owners.values():\n        o.seen = time.monotonic()\n',
        'class M:\n    def start(self, role):\n        run = Run()\n        run.state_pub = self.own_topic("/x")\n',
        'class P:\n    def later(self, coro):\n        self.tasks.add(coro)\n',
    ]
    for source in fine:
        assert not wired_after_construction(source), source


# --- one way to hear of events: rules.hooks ---------------------------------------------------------

EVENT_ROOMS = ('rules', 'runs', 'exercises', 'lab', 'auth', 'media', 'twin', 'web', 'store')
EVENTISH = {'listeners', 'handlers', 'callbacks', 'subscribers', 'observers', 'watchers'}
CONTAINERS = {'list', 'dict', 'set', 'tuple', 'Iterable', 'Sequence', 'Mapping', 'List', 'Dict', 'Set', 'Tuple'}
# (file, what): not events of parts — a process's output lines read as they come, and the SQL reads
# the fleet's thread runs at each beat (their results go to its one listener, ``on_read``)
MECHANISMS_ALLOWED = {
    ('runs/process.py', 'parameter on_line'), ('runs/process.py', 'parameter on_limit'),
    ('store/fleetdb.py', 'self.readers: dict[str, Callable[[sa.Connection, float], Any]] = {}'),
}


def _callables_kept(annotation: ast.AST) -> bool:
    """``list[Callable ...]``, ``dict[str, Callable ...]`` ...: a registry of callbacks."""
    for n in ast.walk(annotation):
        if isinstance(n, ast.Subscript) and isinstance(n.value, ast.Name) and n.value.id in CONTAINERS:
            if any(isinstance(m, ast.Name) and m.id == 'Callable' for m in ast.walk(n.slice)):
                return True
    return False


def event_mechanisms(source: str) -> list[str]:
    """Ways a part could hear of events other than ``rules.hooks``: a callable slot
    (``self.changed = lambda: None``, ``self.on_x = ...``), a registry of callbacks (``self.listeners``,
    ``self.handlers``, an attribute typed a container of ``Callable``), or a callback handed in for
    an event (a parameter named ``on_...``)."""
    lines = source.splitlines()
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            a = node.args
            found += [f'parameter {x.arg}' for x in (*a.posonlyargs, *a.args, *a.kwonlyargs) if x.arg.startswith('on_')]
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        for t in targets:
            if not (isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id == 'self'):
                continue
            if (isinstance(node.value, ast.Lambda) or t.attr.startswith('on_') or t.attr in EVENTISH
                    or (isinstance(node, ast.AnnAssign) and _callables_kept(node.annotation))):
                found.append(lines[node.lineno - 1].strip())
    return found


def test_one_way_to_hear_of_events():
    """Parts hear of each other's events through ``rules.hooks`` alone (a ``Hook`` method each, one
    ``Hooks`` calling them), and the fleet tells the rules through its one typed listener
    (``store.fleet.FleetListener``, the store may not import rules): no second mechanism — no
    callback slot, no list of listeners, no event callback handed to a constructor (issue 52)."""
    files = [GATEWAY / 'server.py'] + [p for room in EVENT_ROOMS for p in sorted((GATEWAY / room).rglob('*.py'))]
    more = [f'{p.relative_to(GATEWAY)}: {what}' for p in files for what in event_mechanisms(p.read_text())
            if (str(p.relative_to(GATEWAY)), what) not in MECHANISMS_ALLOWED]
    assert more == [], 'a second way to hear of events (make it a rules.hooks.Hook event):\n' + '\n'.join(more)
    planted = [
        'class Timetable:\n    def __init__(self):\n        self.changed = lambda: None\n',
        'class Sessions:\n    def __init__(self):\n        self.on_revoked = None\n',
        'class History:\n    def __init__(self):\n        self.listeners = []\n',
        'class Fleet:\n    def __init__(self):\n        self.cut: list[Callable[[], None]] = []\n',
        'class Fleet:\n    def __init__(self):\n        self.lost: dict[str, Callable[[str], None]] = {}\n',
        'class Lease:\n    def __init__(self, on_lost):\n        self.lost = on_lost\n',
    ]
    for source in planted:
        assert event_mechanisms(source), source
    assert not event_mechanisms('class Slots(Hook):\n    def __init__(self, events, now: Callable[[], float]):\n'
                                '        self.events, self.now = events, now\n'
                                '    def on_timetable_changed(self):\n        self.tick()\n')
