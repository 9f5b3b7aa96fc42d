"""Block definitions from outside the IDE are data: checked against the IDE's block schema.

A block with ``"helpUrl": "javascript:..."`` in a share link ran in the gateway's origin when someone
picked Help; with the teacher signed in it published itself to the class's library, so it sat in
every student's toolbox. The page checks every definition it did not write itself (js/blocks/blockcheck.js)
and the gateway checks what it keeps and serves: the class's library (``POST /api/blocks/shared``)
and the block sets of ``--blocks-dir``. Both read one schema, ``ide/blockschema.json``: the keys a
block and its args may have and the kind of value each takes (a url is empty, an http(s) address or
a path of this site), the extensions and mutators the IDE registers, and for every string anywhere:
no HTML tag, no ``javascript:`` or other scheme of ``badSchemes``, at most ``maxString`` characters.
A made block's type starts with ``my_`` (it cannot stand for one of the IDE's own blocks).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

TAG = re.compile(r'<[A-Za-z!/?]')
SCHEME = re.compile(r'([a-z][a-z0-9+.\-]*):')
HIDDEN = re.compile(r'[\x00-\x20\x7f]+')
URL = re.compile(r'https?://[^\s<>"\'`\\]+', re.IGNORECASE)
SITE_PATH = re.compile(r'(?!//)[A-Za-z0-9_./%-]+')
TYPE = re.compile(r'[A-Za-z][A-Za-z0-9_]{0,99}')
WORD = re.compile(r'[A-Za-z0-9_.\- ]{0,100}')
COLOUR = re.compile(r'#[0-9a-fA-F]{6}|\d{1,3}|%\{BKY_[A-Z0-9_]+\}')
NUMBERED = re.compile(r'([A-Za-z]+)(\d)')
ALIGN = frozenset({'LEFT', 'RIGHT', 'CENTRE', 'CENTER'})


class BlockSchema:
    def __init__(self, schema: dict):
        self.s = schema

    @classmethod
    def load(cls, path: Path) -> BlockSchema:
        """The schema in ``path``; one that refuses every block when it cannot be read (no IDE)."""
        try:
            return cls(json.loads(Path(path).read_text()))
        except (OSError, ValueError):
            return Missing({})

    # --- strings anywhere --------------------------------------------------------------------

    def data_problem(self, value, where: str, depth: int = 0) -> str | None:
        """Every string in ``value`` (any JSON) as the schema allows, ``value`` no deeper than maxDepth."""
        if depth > self.s['maxDepth']:
            return f'{where}: nested deeper than {self.s["maxDepth"]} levels'
        if isinstance(value, str):
            return self.text_problem(value, where)
        if isinstance(value, float) and not math.isfinite(value):
            return f'{where}: not a finite number'
        items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
        for key, item in items:
            if isinstance(key, str) and (why := self.text_problem(key, f'{where} (a key)')):
                return why
            why = self.data_problem(item, f'{where}.{key}' if isinstance(key, str) else f'{where}[{key}]', depth + 1)
            if why:
                return why
        return None

    def text_problem(self, text: str, where: str) -> str | None:
        if len(text) > self.s['maxString']:
            return f'{where}: longer than {self.s["maxString"]} characters'
        if TAG.search(text):
            return f'{where}: no HTML in a block ({text[:60]!r})'
        scheme = SCHEME.match(HIDDEN.sub('', text).lower())
        if scheme and scheme.group(1) in self.s['badSchemes']:
            return f'{where}: no {scheme.group(1)}: address in a block'
        return None

    # --- a block -----------------------------------------------------------------------------

    def block_problem(self, block, where: str = 'block', *, made: bool = False) -> str | None:
        """Why ``block`` (Blockly JSON with its ``rosgate`` spec) is not data the IDE takes, or None.
        made: a block of "make a block" (the class's library, a program's own blocks)."""
        if not isinstance(block, dict):
            return f'{where}: a block definition is a JSON object'
        why = self.data_problem(block, where)
        if why:
            return why
        for key, value in block.items():
            numbered = NUMBERED.fullmatch(key)
            name = numbered.group(1) if numbered and numbered.group(1) in self.s['numbered'] else key
            kind = self.s['block'].get(name)
            if kind is None:
                return f'{where}.{key}: not a key of a block ({", ".join(sorted(self.s["block"]))})'
            why = self._value(kind, value, f'{where}.{key}', made)
            if why:
                return why
        kind = block.get('type')
        if not isinstance(kind, str) or not TYPE.fullmatch(kind):
            return f'{where}.type: letters, digits and _, starting with a letter'
        if made and not kind.startswith(self.s['madePrefix']):
            return f'{where}.type: a made block\'s type starts with {self.s["madePrefix"]}'
        return None

    def made_problem(self, made, where: str = 'block') -> str | None:
        """A made block: {"json": block, "spec": spec, "toolboxInputs": {...}}."""
        if not isinstance(made, dict) or not isinstance(made.get('json'), dict):
            return f'{where}: a made block is {{"json": {{...}}, "spec": {{...}}, "toolboxInputs": {{...}}}}'
        for key, value in made.items():
            kind = self.s['made'].get(key)
            if kind is None:
                return f'{where}.{key}: not a key of a made block (json, spec, toolboxInputs)'
            why = self.block_problem(value, f'{where}.json', made=True) if kind == 'block' else (
                self.data_problem(value, f'{where}.{key}') or self._value(kind, value, f'{where}.{key}', True))
            if why:
                return why
        return None

    def set_problem(self, data, where: str = 'set') -> str | None:
        """A block set of --blocks-dir: its blocks, and its toolbox and shadows as data."""
        for key in ('toolbox', 'shadows', 'name', 'robot', 'colour'):
            if key in data and (why := self.data_problem(data[key], f'{where}.{key}')):
                return why
        for i, block in enumerate(data.get('blocks') or ()):
            if why := self.block_problem(block, f'{where}.blocks[{i}]'):
                return why
        return None

    # --- values by kind ----------------------------------------------------------------------

    def _value(self, kind: str, value, where: str, made: bool) -> str | None:
        if kind == 'args':
            return self._args(value, where)
        if kind == 'options':
            return self._options(value, where)
        test = KINDS.get(kind)
        if test is not None and not test(self.s, value, made):
            return f'{where}: {WANTS.get(kind, kind)}, not {json.dumps(value)[:80]}'
        return None

    def _args(self, args, where: str) -> str | None:
        if not isinstance(args, list) or len(args) > self.s['maxArgs']:
            return f'{where}: a list of at most {self.s["maxArgs"]} inputs and fields'
        for i, arg in enumerate(args):
            at = f'{where}[{i}]'
            if not isinstance(arg, dict) or arg.get('type') not in self.s['argTypes']:
                return f'{at}.type: one of {", ".join(self.s["argTypes"])}'
            for key, value in arg.items():
                kind = self.s['arg'].get(key)
                if kind is None:
                    return f'{at}.{key}: not a key of a block\'s input or field'
                if kind != 'argType' and (why := self._value(kind, value, f'{at}.{key}', False)):
                    return why
        return None

    def _options(self, options, where: str) -> str | None:
        if not isinstance(options, list):
            return f'{where}: a list of [label, value]'
        for i, option in enumerate(options):
            label = option[0] if isinstance(option, list) and len(option) == 2 and isinstance(option[1], str) else None
            if isinstance(label, dict):
                if not set(label) <= {'src', 'width', 'height', 'alt'}:
                    return f'{where}[{i}]: an image option is {{src, width, height, alt}}'
                if why := self._value('url', label.get('src', ''), f'{where}[{i}].src', False):
                    return why
            elif not isinstance(label, str):
                return f'{where}[{i}]: [label, value], both text (or an image label)'
        return None


class Missing(BlockSchema):
    """No schema to read (a gateway without its IDE): every block is refused."""

    def block_problem(self, block, where: str = 'block', *, made: bool = False) -> str | None:
        return f'{where}: the IDE\'s block schema (blockschema.json) is missing, so no block is taken'

    def made_problem(self, made, where: str = 'block') -> str | None:
        return self.block_problem(made, where)

    def set_problem(self, data, where: str = 'set') -> str | None:
        return self.block_problem(data, where)


WANTS = {'word': 'a name of letters, digits, _, . and -', 'words': 'a list of names', 'bool': 'true or false',
         'number': 'a number', 'align': 'LEFT, RIGHT or CENTRE', 'check': 'a type name, a list of them or null',
         'colour': 'a hue (0-360), #rrggbb or %{BKY_...}', 'text': 'text', 'scalar': 'a text, number or true/false',
         'url': 'empty, an http(s) address or a path of this site', 'type': 'text',
         'extensions': 'a list of the IDE\'s own extensions (none for a made block)',
         'mutator': 'one of the IDE\'s own mutators', 'spec': 'a rosgate spec with a known "kind"'}


def _text(v) -> bool:
    return isinstance(v, str)


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


KINDS = {   # kind -> (schema, value, made) -> whether the value is of that kind
    'type': lambda s, v, m: _text(v),
    'text': lambda s, v, m: _text(v),
    'word': lambda s, v, m: _text(v) and bool(WORD.fullmatch(v)),
    'words': lambda s, v, m: isinstance(v, list) and all(_text(x) and WORD.fullmatch(x) for x in v),
    'bool': lambda s, v, m: isinstance(v, bool),
    'number': lambda s, v, m: _number(v),
    'scalar': lambda s, v, m: v is None or isinstance(v, (str, int, float, bool)),
    'align': lambda s, v, m: _text(v) and v in ALIGN,
    'check': lambda s, v, m: v is None or _text(v) or (isinstance(v, list) and all(_text(x) for x in v)),
    'colour': lambda s, v, m: _number(v) or (_text(v) and bool(COLOUR.fullmatch(v))),
    'url': lambda s, v, m: _text(v) and (v == '' or bool(URL.fullmatch(v)) or bool(SITE_PATH.fullmatch(v))),
    'extensions': lambda s, v, m: isinstance(v, list) and not m and all(_text(x) and x in s['extensions'] for x in v),
    'mutator': lambda s, v, m: _text(v) and v in (s['madeMutators'] if m else s['mutators']),
    'spec': lambda s, v, m: isinstance(v, dict) and v.get('kind') in s['specKinds'],
}

