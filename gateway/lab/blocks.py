"""Robots' block sets and the class's shared blocks as files of a folder (``--blocks-dir``): the sets
read (``read_sets``: every ``*.json`` but ``shared.json``, one that is not a set left out with its
reason), the class's library read (``read_shared``: ``shared.json``'s ``{"made": [...]}``), and a made
block checked before it is kept (``check_made``: a ``Refusal`` of 400 naming what is wrong). Each
is checked against the IDE's block schema (``blockcheck``). The HTTP API is ``web.blocksets``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from ..rules.errors import Refusal
from .blockcheck import BlockSchema

SHARED = 'shared.json'
MAX_SHARED = 500                   # blocks in the class's library
MAX_SET_BYTES = 2 * 1024 * 1024
_TYPE = re.compile(r'[A-Za-z][A-Za-z0-9_]{0,99}')


def read_sets(folder: Path, schema: BlockSchema) -> tuple[list[dict], list[dict]]:
    """The block sets in ``folder`` (every *.json but shared.json, by name) and what was skipped."""
    sets, skipped = [], []
    for path in sorted(folder.glob('*.json')):
        if path.name == SHARED or not path.is_file():
            continue
        try:
            if path.stat().st_size > MAX_SET_BYTES:
                raise ValueError(f'larger than {MAX_SET_BYTES} bytes')
            data = json.loads(path.read_bytes())
            if not isinstance(data, dict) or not isinstance(data.get('blocks'), list):
                raise ValueError('not a block set: it needs "blocks": [...]')
            if not all(isinstance(b, dict) and _TYPE.fullmatch(str(b.get('type', ''))) for b in data['blocks']):
                raise ValueError('each block needs a "type" of letters, digits and _')
            problem = schema.set_problem(data, path.name)
            if problem:
                raise ValueError(problem)
        except (OSError, ValueError) as e:
            skipped.append({'file': path.name, 'why': str(e)[:300]})
            continue
        sets.append({'file': path.name, 'name': str(data.get('name') or path.stem), 'robot': str(data.get('robot') or '*'),
                     'colour': data.get('colour', 200), 'namespaced': bool(data.get('namespaced')),
                     **{k: data[k] for k in ('toolbox', 'shadows') if k in data}, 'blocks': data['blocks']})
    return sets, skipped


def read_shared(folder: Path, schema: BlockSchema) -> list[dict]:
    """The class's library: the kept blocks the schema takes (one written before it was checked
    is left out)."""
    try:
        made = json.loads((folder / SHARED).read_bytes()).get('made', [])
    except (OSError, ValueError, AttributeError, RecursionError):
        return []
    return [m for m in made if schema.made_problem(m) is None] if isinstance(made, list) else []


def check_made(made: dict, schema: BlockSchema) -> str:
    """The type of a made block (``makeblock.buildDefinition``'s {json, spec, toolboxInputs}), or 400
    naming what the schema refuses (``Refusal``)."""
    block = made.get('json')
    if not isinstance(block, dict) or not isinstance(made.get('spec'), dict):
        raise Refusal(400, 'a made block is {"json": {...Blockly JSON}, "spec": {...}}')
    kind = str(block.get('type', ''))
    if not _TYPE.fullmatch(kind):
        raise Refusal(400, f'the block\'s "type" {kind[:100]!r} is not letters, digits and _')
    problem = schema.made_problem(made, 'body')
    if problem:
        raise Refusal(400, problem)
    return kind
