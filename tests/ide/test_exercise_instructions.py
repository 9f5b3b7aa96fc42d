"""An exercise's instructions and title in the reader's language, in Chromium: its Markdown stands
beside the editor (the side panel's top), rendered with no HTML of the teacher's (a <script>, an
<img onerror> and a javascript: link stay harmless text), and its title in the bar and the
program's name follow ?lang=. The class view shows the title in the teacher's language too."""

from __future__ import annotations

import json

import pytest

from tests.support.ide import TABLET, IdePage, drive, program

CORNER = {
    'title': 'The far corner', 'titles': {'es': 'La esquina lejana', 'de': 'Die ferne Ecke'},
    'time_limit': 30, 'pose_topic': 'turtle1/pose',
    'start': {'blocks': program(drive(seconds=1, speed=0.5), name='')},
    'instructions': {
        'en': ('Drive the turtle to the **bottom left** corner.\n\n1. Turn\n2. Drive\n\n'
               'Read [the guide](https://docs.ros.org/) first. <script>window.hacked = 1</script>\n\n'
               '<img src=x onerror="window.hacked = 2"> [click](javascript:window.hacked=3)'),
        'es': 'Lleva la tortuga a la esquina **inferior izquierda**.',
    },
    'goal': {'region': {'xmin': 0, 'xmax': 0.5, 'ymin': 0, 'ymax': 0.5}},
}


@pytest.fixture(scope='module')
def gw(launch, tmp_path_factory):
    folder = tmp_path_factory.mktemp('instructions')
    (folder / 'corner.json').write_text(json.dumps(CORNER))
    return launch('--robot', 'turtlesim', '--exercises-dir', str(folder))


def opened(chromium, gw, query: str) -> tuple:
    ctx = chromium.new_context(viewport=TABLET)
    ide = IdePage(ctx.new_page(), gw).open(gw.http_url + query)
    ide.page.wait_for_selector('#instructions .markdown', timeout=20000)
    return ctx, ide


def test_the_instructions_stand_beside_the_editor_as_markdown_and_nothing_runs(chromium, gw):
    ctx, ide = opened(chromium, gw, '?exercise=corner&lang=en')
    try:
        page = ide.page
        panel = page.locator('#instructions')
        assert panel.locator('h2').inner_text() == 'The far corner'
        assert panel.locator('strong').inner_text() == 'bottom left'
        assert panel.locator('ol li').all_inner_texts() == ['Turn', 'Drive']
        link = panel.locator('a', has_text='the guide')
        assert link.get_attribute('href') == 'https://docs.ros.org/' and link.get_attribute('target') == '_blank'
        assert 'noopener' in link.get_attribute('rel')
        # the teacher's HTML is text, and a javascript: link is no link
        assert panel.locator('script, img').count() == 0
        text = panel.inner_text()
        assert '<script>window.hacked = 1</script>' in text and '<img src=x onerror=' in text, text
        assert page.locator('#instructions a[href^="javascript"]').count() == 0
        panel.locator('.markdown').click()
        assert page.evaluate('window.hacked') is None
        # beside the editor: in the side panel, above the world view, both on screen
        box, side = panel.bounding_box(), page.locator('#side').bounding_box()
        assert side['x'] <= box['x'] and box['x'] + box['width'] <= side['x'] + side['width'] + 1
        assert box['y'] < page.locator('#world').bounding_box()['y']
        assert page.locator('#blockly').bounding_box()['x'] + 10 < box['x']
        assert 'The far corner' in page.inner_text('#exercise-status')
        assert not ide.errors, ide.errors
    finally:
        ctx.close()


def test_title_and_instructions_in_spanish(chromium, gw):
    ctx, ide = opened(chromium, gw, '?exercise=corner&lang=es')
    try:
        page = ide.page
        assert page.inner_text('#instructions h2') == 'La esquina lejana'
        assert 'Lleva la tortuga' in page.inner_text('#instructions') and 'Drive the turtle' not in page.inner_text('#instructions')
        assert page.locator('#instructions strong').inner_text() == 'inferior izquierda'
        assert page.inner_text('#exercise-status') == 'La esquina lejana'
        page.wait_for_function("rosgateIde.programName === 'La esquina lejana'")
        assert page.get_attribute('#instructions', 'aria-label') == 'Instrucciones'
        assert not ide.errors, ide.errors
    finally:
        ctx.close()


def test_french_falls_back_to_english(chromium, gw):
    ctx, ide = opened(chromium, gw, '?exercise=corner&lang=fr')
    try:
        assert ide.page.inner_text('#instructions h2') == 'The far corner'
        assert 'Drive the turtle' in ide.page.inner_text('#instructions')
    finally:
        ctx.close()
