"""ROS 2 names as rcl checks them: a fully qualified topic or service name (the rules of rmw's
``rmw_validate_full_topic_name``, after rcl's expansion; ROS 2 design, "Topic and Service name
mapping to DDS").

A valid name is absolute (starts with ``/``), has no trailing ``/`` and no ``//``, holds only ASCII
letters, digits, ``_`` and ``/``, no token of it starts with a digit, and it is at most
``MAX_LENGTH`` characters (255 less the 8 DDS keeps for its prefixes). The embedded sim refuses
what rcl refuses, so a name with a space, a newline, a ``<`` or a right-to-left override is never
created and never listed to anyone.
"""

from __future__ import annotations

import re

MAX_LENGTH = 255 - 8
_ALLOWED = re.compile(r'[A-Za-z0-9_/]*')


def name_problem(name: str) -> str | None:
    """Why ``name`` is no valid fully qualified ROS 2 topic or service name, or None."""
    if not isinstance(name, str) or not name:
        return 'a name is not empty'
    if not name.startswith('/'):
        return 'a full name starts with /'
    if len(name) > 1 and name.endswith('/'):
        return 'a name does not end with /'
    if not _ALLOWED.fullmatch(name):
        bad = next(c for c in name if not (c.isascii() and (c.isalnum() or c in '_/')))
        return f'a name holds only ASCII letters, digits, _ and /, not {bad!r} (at {name.index(bad)})'
    if '//' in name:
        return 'a name has no //'
    if any(token[:1].isdigit() for token in name.split('/')):
        return 'no part of a name starts with a digit'
    if len(name) > MAX_LENGTH:
        return f'a name is at most {MAX_LENGTH} characters, not {len(name)}'
    return None
