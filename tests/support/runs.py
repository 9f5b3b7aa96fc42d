"""Robot-side runs (/api/runs): programs as the IDE generates them, and a run's state over HTTP."""

from __future__ import annotations

from pathlib import Path

from tests.support.http import api
from tests.support.process import ROOT
from tests.support.wait import wait_for

RUNTIME = (ROOT / 'ide' / 'runtime' / 'rosgate_runtime.py').read_text()
ENDED = ('finished', 'failed', 'stopped', 'timed_out')


def program(body: str) -> str:
    """A program as the IDE generates it: the runtime, then main()."""
    lines = ''.join(f'    {line}\n' for line in body.strip().splitlines())
    return f'{RUNTIME}\n\ndef main():\n{lines}\n\nif __name__ == "__main__":\n    run(main)\n'


def state_of(gw, run_id: str, token: str | None = None) -> dict:
    status, body = api(gw, 'GET', f'/api/runs/{run_id}', token=token)
    assert status == 200, body
    return body


def ended(gw, run_id: str, timeout: float = 60, token: str | None = None) -> dict:
    return wait_for(lambda: (lambda s: s if s['state'] in ENDED else None)(state_of(gw, run_id, token)), timeout, 0.05)


def alive(marker: str) -> list[int]:
    """This machine's processes (zombies aside) with ``marker`` in their command line, seen from here."""
    found = []
    for entry in Path('/proc').iterdir():
        try:
            if entry.name.isdigit() and marker.encode() in (entry / 'cmdline').read_bytes() \
                    and (entry / 'stat').read_text().rsplit(')', 1)[1].split()[0] != 'Z':
                found.append(int(entry.name))
        except OSError:
            pass
    return found
