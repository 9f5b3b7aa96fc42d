"""The IDE's console follows its newest line while the reader has not scrolled up, also when the
box around it changes size (a banner above it, a rotated tablet): the end moving without her is
not her scrolling away. A CI run caught "Stopped by the teacher" out of sight under the banner
that said the same."""

from __future__ import annotations

IN_SIGHT = """() => {
  const box = document.querySelector('#console').getBoundingClientRect();
  const r = document.querySelector('#console-lines').lastElementChild.getBoundingClientRect();
  return box.top <= r.top && r.bottom <= box.bottom + 1;
}"""


def log(ide, *lines):
    ide.js("(lines) => lines.forEach((l) => rosgateIde.console.log(l))", list(lines))


def test_the_console_follows_its_newest_line_until_the_reader_scrolls_up(gateway, ide_factory):
    ide = ide_factory(gateway)
    log(ide, *[f"line {i}" for i in range(60)])
    ide.page.wait_for_function(IN_SIGHT, timeout=5000)
    # the box shrinks (as under a banner), then a line comes: in sight
    ide.js("() => { document.querySelector('#console').style.height = '100px'; }")
    ide.page.wait_for_function("document.querySelector('#console').clientHeight <= 100")
    log(ide, "after the box shrank")
    ide.page.wait_for_function(IN_SIGHT, timeout=5000)
    assert ide.js("document.querySelector('#console-lines').lastElementChild.textContent") == "after the box shrank"
    # the reader scrolls up: new lines leave her where she reads
    ide.js("() => { document.querySelector('#console').scrollTop = 0; }")
    ide.page.wait_for_function("rosgateIde.console.pinned === false")
    log(ide, "while she reads")
    ide.page.evaluate("new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")   # two frames
    assert ide.js("document.querySelector('#console').scrollTop") == 0
    # back at the end, it follows again
    ide.js("() => { const c = document.querySelector('#console'); c.scrollTop = c.scrollHeight; }")
    ide.page.wait_for_function("rosgateIde.console.pinned === true")
    log(ide, "followed again")
    ide.page.wait_for_function(IN_SIGHT, timeout=5000)
    assert not ide.errors, ide.errors
