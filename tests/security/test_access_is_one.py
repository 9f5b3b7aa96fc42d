"""No role compared outside the access module: an AST walk of gateway/ (issue 52's bar).

Who may do what is decided in ``gateway/rules/access.py`` alone (``decide`` over its table, the
websocket's ``PERMISSIONS``, ``StationGrants`` for the claims and the lease). Anywhere else a role
may be passed on or reported (``/whoami``'s answer, an X-Rosgate-Role header, a log line, a run
inheriting its starter's role) but not compared. The walk finds, outside access.py:

- a comparison (``==``, ``!=``, ``in``, ``not in``) with a role's word ('viewer', 'operator', 'admin')
  or a tuple of them, a ``.role``/``.takeover_role``/``.admin_role`` attribute, ``role_of(...)``, a
  ``['role']`` item or ``.get('role')``, or a name of the role sets (``ROLES``, ``RANKS``,
  ``GATEWAY_ROLE``) on either side; ``x.role is None`` (whether there is a role at all) passes;
- the role tuples ``ADMINS``, ``OPERATORS``, ``EVERYONE`` used at all;
- a ``roles=`` keyword argument (the old ``caller(..., roles=...)``);
- a call of ``is_admin`` or ``acts_as_admin`` (ask ``decide`` or ``allowed`` instead).

``test_the_walk_finds_each_shape`` plants each shape in a snippet and sees it found."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ACCESS = Path('gateway/rules/access.py')
ROLE_WORDS = frozenset({'viewer', 'operator', 'admin'})
ROLE_ATTRS = frozenset({'role', 'takeover_role', 'admin_role'})
ROLE_SETS = frozenset({'ROLES', 'RANKS', 'GATEWAY_ROLE'})
ROLE_TUPLES = frozenset({'ADMINS', 'OPERATORS', 'EVERYONE'})
ASKERS = frozenset({'is_admin', 'acts_as_admin'})
COMPARING = (ast.Eq, ast.NotEq, ast.In, ast.NotIn)
# Comparisons of roles that decide no access, each with its reason.
ALLOWED = {
    ('gateway/auth/tokens.py', 'listed'): 'whether a token file still holds this Identity (its name and role): '
                                            'equality of records, read by the sessions, not a permission',
    ('gateway/lab/roster.py', 'fetch'): 'roles= is a column of the roster: the LMS\'s own membership roles, '
                                          'kept as the LMS sent them',
}


def _is_role_word(node: ast.AST) -> bool:
    if isinstance(node, ast.Constant):
        return node.value in ROLE_WORDS
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return any(_is_role_word(e) for e in node.elts)
    return False


def _is_role(node: ast.AST) -> bool:
    """Whether an operand of a comparison is a role (or a set of roles)."""
    if _is_role_word(node):
        return True
    if isinstance(node, ast.Attribute) and node.attr in ROLE_ATTRS:
        return True
    if isinstance(node, ast.Name) and node.id in ROLE_SETS | ROLE_TUPLES:
        return True
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value == 'role':
        return True
    if isinstance(node, ast.Call):
        func = node.func
        if isinstance(func, ast.Name) and func.id == 'role_of':
            return True
        if (isinstance(func, ast.Attribute) and func.attr == 'get' and node.args
                and isinstance(node.args[0], ast.Constant) and node.args[0].value == 'role'):
            return True
    return False


def _function_of(tree: ast.AST) -> dict[ast.AST, str]:
    """Each node -> the name of the innermost function holding it ('' at module level)."""
    owner: dict[ast.AST, str] = {}

    def visit(node: ast.AST, name: str) -> None:
        for child in ast.iter_child_nodes(node):
            inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else name
            owner[child] = inner
            visit(child, inner)
    visit(tree, '')
    return owner


def role_comparisons(source: str, path: str = '<snippet>') -> list[str]:
    """Every place in ``source`` that compares or tests a role outside the access module."""
    tree = ast.parse(source)
    where = _function_of(tree)
    found = []

    def note(node: ast.AST, what: str) -> None:
        if (path, where.get(node, '')) not in ALLOWED:
            found.append(f'{path}:{node.lineno}: {what}: {ast.unparse(node)[:100]}')

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            operands = [node.left, *node.comparators]
            if any(isinstance(op, COMPARING) for op in node.ops) and any(_is_role(o) for o in operands):
                note(node, 'a role compared')
        elif isinstance(node, ast.Name) and node.id in ROLE_TUPLES:
            note(node, f'the role tuple {node.id}')
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if alias.name in ROLE_TUPLES | ASKERS:
                    note(node, f'{alias.name} imported')
        elif isinstance(node, ast.keyword) and node.arg == 'roles':
            note(node.value, 'a roles= argument')
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ASKERS:
            note(node, f'{node.func.id}() asked')
    return found


def test_no_role_compared_outside_the_access_module():
    found = []
    for file in sorted((ROOT / 'gateway').rglob('*.py')):
        rel = file.relative_to(ROOT)
        if rel == ACCESS:
            continue
        found += role_comparisons(file.read_text(encoding='utf-8'), rel.as_posix())
    assert not found, 'roles compared outside gateway/rules/access.py (ask access.decide):\n' + '\n'.join(found)


PLANTED = {
    'identity.role == "admin"': 'a role compared',
    'who.role != viewer_role': 'a role compared',
    '"operator" in roles_of_someone': 'a role compared',
    'role in ("operator", "admin")': 'a role compared',
    'role not in ADMINS': 'a role compared',
    'x = OPERATORS': 'the role tuple OPERATORS',
    'from gateway.rules.access import EVERYONE': 'EVERYONE imported',
    'caller(self, gw, change=True, roles=("admin",))': 'a roles= argument',
    'session.attrs.get("role") == GATEWAY_ROLE': 'a role compared',
    'session.attrs["role"] == "gateway"': 'a role compared',
    'role_of(asker) == lease.takeover_role': 'a role compared',
    'self.admin_role is None or r == self.admin_role': 'a role compared',
    'want in RANKS': 'a role compared',
    'level if level in ROLES else None': 'a role compared',
    'if is_admin(who): pass': 'is_admin() asked',
    'from ..rules.access import acts_as_admin': 'acts_as_admin imported',
}


def test_the_walk_finds_each_shape():
    for snippet, what in PLANTED.items():
        found = role_comparisons(snippet)
        assert found and what in found[0], f'{snippet!r} not found as {what!r}: {found}'


def test_the_walk_lets_a_role_be_passed_on_and_reported():
    passed = '''
def whoami(handler, identity):
    handler.set_header('X-Rosgate-Role', identity.role)
    handler.finish({'auth': True, 'name': identity.name, 'role': identity.role})
    if run.role is not None:
        session.attrs['role'] = run.role
    log.info('%s (%s)', identity.name, identity.role)
    return decide(identity, Action.CHANGE, Area.RUNS) is None
'''
    assert role_comparisons(passed) == []


def test_the_walk_finds_a_violation_planted_in_a_gateway_module():
    """The walk of the real tree, with one module's text changed as a slip would change it."""
    path = 'gateway/web/runs.py'
    text = (ROOT / path).read_text(encoding='utf-8')
    assert role_comparisons(text, path) == []
    slipped = text.replace("allowed(identity, Action.MANAGE, Area.RUNS)",
                           "identity is None or identity.role == 'admin'", 1)
    assert slipped != text
    assert [f for f in role_comparisons(slipped, path) if 'a role compared' in f]
