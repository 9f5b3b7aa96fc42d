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
a new publish of a type replacing it), written whole (``lab.programs.write_whole``). Without
--blocks-dir the lists are empty and a publish gets 404. With --auth, a valid token reads.
What is published, kept and served is data: checked against the IDE's block schema (``blockcheck``:
no ``javascript:`` or other non-http(s) address, no HTML); a publish that is not is a 400 naming
the field, and a set or a kept block that is not is left out (``skipped``). Reading and checking
them is ``lab.blocks``'.
"""

from __future__ import annotations

import json
from pathlib import Path

import tornado.web

from ..lab.blockcheck import BlockSchema
from ..lab.blocks import MAX_SHARED, SHARED, check_made, read_shared, read_sets
from ..lab.programs import write_whole
from ..rules.access import Action, Area, allowed
from .api import JsonHandler, authorized, body_json

SCHEMA = 'blockschema.json'       # in the IDE's folder: what a block from outside may hold (blockcheck)
MAX_BLOCK_BYTES = 256 * 1024       # a made block with eight inputs is ~3 KB


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
