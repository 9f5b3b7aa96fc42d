"""The dashboard's gauge limits from ``--gauges FILE`` (JSON or TOML), checked: what ``GET /api/gauges``
(``web.gauges``) answers and what the start-up check (``cli.check``) reads once. The file's form is
in ``web.gauges``.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

KEYS = frozenset({'min', 'max', 'warn', 'danger', 'low'})
PARTS = frozenset({'effort', 'temperature'})


def _check(name: str, entry, where: str) -> None:
    if not isinstance(entry, dict):
        raise ValueError(f'{where}: the entry of {name!r} is not a table of limits')
    for key, value in entry.items():
        if key in PARTS and not where.endswith(f'.{key}'):
            _check(name, value, f'{where}.{key}')
        elif key == 'low':
            if not isinstance(value, bool):
                raise ValueError(f'{where}: {name!r}: "low" is true or false')
        elif key in KEYS:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f'{where}: {name!r}: {key!r} is not a number')
        else:
            raise ValueError(f'{where}: {name!r}: unknown key {key!r} (one of {", ".join(sorted(KEYS | PARTS))})')


def read_limits(path: Path) -> dict:
    """The limits in a --gauges file; ValueError saying what is wrong with it."""
    text = Path(path).read_bytes()
    try:
        data = tomllib.loads(text.decode()) if Path(path).suffix == '.toml' else json.loads(text)
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f'{path}: {e}') from None
    if not isinstance(data, dict):
        raise ValueError(f'{path}: not a table of topic names')
    for name, entry in data.items():
        _check(name, entry, str(path))
    return data
