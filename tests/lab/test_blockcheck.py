"""The block schema's check on the gateway (gateway/lab/blockcheck.py), in-process, on the cases the
page's check (ide/js/blocks/blockcheck.js) is run on too (tests/node/blockcheck.test.js): the two agree,
so what the page refuses the gateway refuses and the other way round. From outside:
tests/security/test_class_doors.py (the class's library) and tests/ide/test_shared_content.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gateway.lab.blockcheck import BlockSchema

ROOT = Path(__file__).resolve().parents[2]
CASES = json.loads((ROOT / 'tests' / 'node' / 'blockcases.json').read_text())
SCHEMA = BlockSchema.load(ROOT / 'ide' / 'blockschema.json')


@pytest.mark.parametrize('case', CASES, ids=[c['what'] for c in CASES])
def test_a_made_block(case):
    why = SCHEMA.made_problem(case['made'])
    if case['bad'] is False:
        assert why is None, why
    else:
        assert why is not None and case['bad'] in why, why


@pytest.mark.parametrize('name', sorted(p.name for p in (ROOT / 'ide' / 'blocks').glob('*.json')))
def test_the_ides_own_sets_pass(name):
    assert SCHEMA.set_problem(json.loads((ROOT / 'ide' / 'blocks' / name).read_text()), name) is None


def test_without_its_schema_no_block_is_taken(tmp_path):
    missing = BlockSchema.load(tmp_path / 'none.json')
    assert 'missing' in missing.made_problem(CASES[0]['made'])
