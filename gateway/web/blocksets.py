"""Robots' block sets and the class's shared blocks, from a folder (``--blocks-dir DIR``):

GET  /api/blocks          -> {"sets": [SET, ...], "shared": [MADE, ...], "publish": bool}
POST /api/blocks/shared   -> publish one made block (the IDE's "make a block" definition) to the
                             class: {"type", "shared": n}; admins only (403 otherwise)

A block set is a JSON file ``DIR/NAME.json`` in the form of the IDE's own sets (``ide/blocks``):
``{"name", "colour", "namespaced", "robot", "blocks": [Blockly JSON with a "rosgate" spec]}``;
``robot`` is a glob of robot namespaces (``/husky*``; ``/`` for a gateway's one robot without a
namespace; absent or ``*``: every robot), and the IDE lists the set in its toolbox only for a robot
it matches. Sets are read on each request (a teacher drops a file in, the next page load has it);
a file that is not a set is left out with its reason in ``skipped``, so one typo hides one set.
Published blocks are kept in ``DIR/shared.json`` (``{"made": [MADE, ...]}``, one per block type,
a new publish of a type replacing it), written whole (``programs.write_whole``). Without
--blocks-dir the lists are empty and a publish gets 404. With --auth, a valid token reads.
What is published, kept and served is data: checked against the IDE's block schema (``blockcheck``:
no ``javascript:`` or other non-http(s) address, no HTML); a publish that is not is a 400 naming
the field, and a set or a kept block that is not is left out (``skipped``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import tornado.web

from ..rules.access import Action, Area, allowed
from .api import JsonHandler, authorized, body_json
from ..lab.blockcheck import BlockSchema
from .programs import write_whole

SHARED = 'shared.json'
SCHEMA = 'blockschema.json'       # in the IDE's folder: what a block from outside may hold (blockcheck)
MAX_BLOCK_BYTES = 256 * 1024       # a made block with eight inputs is ~3 KB
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
    naming what the schema refuses."""
    block = made.get('json')
    if not isinstance(block, dict) or not isinstance(made.get('spec'), dict):
        raise tornado.web.HTTPError(400, 'a made block is {"json": {...Blockly JSON}, "spec": {...}}')
    kind = str(block.get('type', ''))
    if not _TYPE.fullmatch(kind):
        raise tornado.web.HTTPError(400, f'the block\'s "type" {kind[:100]!r} is not letters, digits and _')
    problem = schema.made_problem(made, 'body')
    if problem:
        raise tornado.web.HTTPError(400, problem)
    return kind


class BlocksHandler(JsonHandler):
    def initialize(self, folder: Path | None, schema: BlockSchema) -> None:
        self.folder, self.schema = folder, schema

    @authorized(Area.BLOCKS)
    def get(self) -> None:
        admin = allowed(self.identity, Action.CHANGE, Area.BLOCKS)   # may publish to the class
        if self.folder is None:
            self.finish({'sets': [], 'shared': [], 'publish': False})
            return
        sets, skipped = read_sets(self.folder, self.schema)
        self.finish({'sets': sets, 'shared': read_shared(self.folder, self.schema), 'skipped': skipped,
                     'publish': admin})


class SharedHandler(JsonHandler):
    def initialize(self, folder: Path | None, schema: BlockSchema) -> None:
        self.folder, self.schema = folder, schema

    @authorized(Area.BLOCKS, Action.CHANGE, words='{name} may not publish blocks to the class: an admin may')
    def post(self) -> None:
        if self.folder is None:
            raise tornado.web.HTTPError(404, 'this gateway keeps no shared blocks (start it with --blocks-dir DIR)')
        made = body_json(self, MAX_BLOCK_BYTES)
        kind = check_made(made, self.schema)
        shared = [m for m in read_shared(self.folder, self.schema) if (m.get('json') or {}).get('type') != kind] + [made]
        if len(shared) > MAX_SHARED:
            raise tornado.web.HTTPError(507, f'the class\'s library holds {MAX_SHARED} blocks; this one is one more')
        write_whole(self.folder / SHARED, json.dumps({'made': shared}, separators=(',', ':')).encode())
        self.finish({'type': kind, 'shared': len(shared)})


def block_routes(folder: Path | None, ide_dir: Path) -> list:
    """``folder``: --blocks-dir (``Settings.storage.blocks_dir``) or None; ``ide_dir``: where the block schema is."""
    kw = {'folder': Path(folder).expanduser() if folder else None, 'schema': BlockSchema.load(ide_dir / SCHEMA)}
    return [(r'/api/blocks/?', BlocksHandler, kw), (r'/api/blocks/shared', SharedHandler, kw)]
