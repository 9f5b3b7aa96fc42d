"""The pages in the reader's language, in Chromium: ?lang=, a Spanish browser, the language menu
remembered over a reload, English for a string or a language the files lack, the blocks and
Blockly's own words, numbers in the reader's locale, and the gateway's login page."""

from __future__ import annotations

import json
import re
import urllib.request

import pytest

from tests.support.ide import IdePage
from tests.support.lesson import open_ide
from tests.support.process import ROOT

ES = json.loads((ROOT / 'ide/i18n/es.json').read_text())
DE = json.loads((ROOT / 'ide/i18n/de.json').read_text())
EN = json.loads((ROOT / 'ide/i18n/en.json').read_text())


@pytest.fixture(scope='module')
def gw(start_gateway):
    return start_gateway('--robot', 'turtlesim', '--fleet', '2', '--exclusive-control')


@pytest.fixture
def context(chromium):
    made = []

    def make(**kw):
        ctx = chromium.new_context(**{'viewport': {'width': 1400, 'height': 860}, **kw})
        made.append(ctx)
        return ctx

    yield make
    for ctx in made:
        ctx.close()


def categories(ide: IdePage) -> list[str]:
    return ide.js("rosgateIde.workspace.getToolbox().getToolboxItems().map((i) => i.getName?.()).filter(Boolean)")


def block_text(ide: IdePage, block_type: str) -> str:
    """The words a new block of `block_type` shows on the workspace."""
    return ide.js("""(t) => { const b = rosgateIde.workspace.newBlock(t); b.initSvg(); b.render();
      const text = b.getSvgRoot().textContent; b.dispose(); return text; }""", block_type).replace("\xa0", " ")


def test_ide_in_spanish_by_lang_parameter(gw, context):
    ide = open_ide(context(), gw, '?lang=es')
    assert ide.js('document.documentElement.lang') == 'es'
    assert ide.js('document.documentElement.dir') == 'ltr'
    names = categories(ide)
    assert names[:7] == ['Lógica', 'Bucles', 'Matemáticas', 'Texto', 'Listas', 'Variables', 'Funciones'], names
    assert 'Mis bloques' in names
    assert ide.page.inner_text('#run') == '▶ Ejecutar'
    assert ide.page.inner_text('#stop') == '■ Detener'
    assert ide.page.inner_text('#new') == 'Nuevo'
    assert ide.page.get_attribute('#share', 'title') == ES['ide.share.title']
    assert ide.page.inner_text('#status') == 'conectado'
    # Blockly's own blocks and the project's, in Spanish
    assert ide.js('Blockly.Msg.CONTROLS_IF_MSG_IF') == 'si'
    assert 'mover' in block_text(ide, 'turtle_move') and 'move' not in block_text(ide, 'turtle_move').replace('mover', '')
    assert 'detener el robot' in block_text(ide, 'ros_stop')
    assert block_text(ide, 'ros_message').startswith('mensaje')
    assert 'Lógica' in ide.page.inner_text('.blocklyToolbox')
    # the language menu says which language this is
    assert ide.page.input_value('#lang') == 'es'
    assert not ide.errors, ide.errors


def test_a_spanish_browser_gets_spanish_without_lang(gw, context):
    ide = open_ide(context(locale='es-ES'), gw)
    assert ide.js('navigator.language') == 'es-ES'
    assert ide.js('document.documentElement.lang') == 'es'
    assert categories(ide)[0] == 'Lógica'
    assert ide.page.inner_text('#run') == '▶ Ejecutar'
    # ?lang= wins over the browser's language
    other = open_ide(context(locale='es-ES'), gw, '?lang=fr')
    assert other.page.inner_text('#run') == '▶ Exécuter'
    assert categories(other)[0] == 'Logique'


def test_the_menu_choice_is_remembered_after_a_reload(gw, context):
    ctx = context()
    ide = open_ide(ctx, gw)
    assert ide.page.inner_text('#run') == '▶ Run'                 # English by default
    with ide.page.expect_navigation():
        ide.page.select_option('#lang', 'de')
    ide.page.wait_for_function("document.body?.dataset.ready === 'true'")
    assert ide.page.inner_text('#run') == DE['ide.run']
    ide.page.reload()
    ide.page.wait_for_function("document.body?.dataset.ready === 'true'")
    assert ide.page.inner_text('#run') == DE['ide.run']
    assert categories(ide)[0] == 'Logik'
    # the other pages of this browser follow the choice, the gateway's login page too
    teleop = ctx.new_page()
    teleop.goto(gw.http_url + 'teleop')
    teleop.wait_for_function("document.body?.dataset.ready === 'true'")
    assert teleop.inner_text('label[for=maxspeed]') == DE['teleop.maxspeed']
    login = ctx.new_page()
    login.goto(gw.http_url + 'login')
    assert login.inner_text('button') == 'Anmelden'
    assert login.evaluate('document.documentElement.lang') == 'de'


def test_teleop_in_spanish_with_numbers_in_the_spanish_way(gw, context):
    page = context().new_page()
    page.goto(gw.http_url + 'teleop?lang=es')
    page.wait_for_function("document.body?.dataset.ready === 'true'")
    page.wait_for_function("document.body?.dataset.connection === 'connected'")
    assert page.inner_text('#status') == 'conectado'
    assert page.inner_text('label[for=maxspeed]') == 'velocidad máx.'
    assert page.get_attribute('[data-key=up]', 'aria-label') == 'adelante'
    assert page.inner_text('#claim') == 'Pedir un robot' or not page.is_visible('#claim')
    assert page.evaluate("document.querySelector('#claim').textContent") == 'Pedir un robot'
    assert page.inner_text('#maxspeed-out') == '0,50 m/s'                     # a decimal comma
    assert page.inner_text('#cmd') == 'lineal 0,00 m/s · angular 0,00 rad/s'
    assert page.inner_text('#plot-span option[value="3600"]') == 'última hora'
    # the 3D panel (the twin page in a frame, without ?lang=: the tab's language holds)
    page.click('#twin-show')
    assert page.inner_text('#twin-show') == 'ocultar'
    twin = page.frame_locator('#twin-frame')
    twin.locator('html[lang=es]').wait_for(state='attached')
    assert twin.locator('#battery').inner_text() == 'batería –'
    assert twin.locator('#view').get_attribute('aria-label') == ES['twin.view']


def test_class_view_in_spanish(gw, context):
    page = context().new_page()
    page.goto(gw.http_url + 'class?lang=es')
    page.wait_for_function("document.body?.dataset.connection === 'connected'")
    assert page.inner_text('#stop-all') == '■ Detener todo'
    assert page.inner_text('#release-all') == 'Liberar todo'
    page.wait_for_function("document.querySelectorAll('article.tile').length === 2")
    assert page.inner_text('#count').startswith('2 estaciones')
    assert page.inner_text("article.tile[data-ns='/s01'] .stop") == '■ Detener'
    # the earlier tests' pages claimed a station: "estación de …", the other is "libre"
    holders = page.evaluate("[...document.querySelectorAll('article.tile .holder')].map((e) => e.textContent)")
    assert all(h == 'libre' or h.startswith('estación de ') for h in holders), holders


def test_a_missing_string_or_language_falls_back_to_english(gw, context):
    ctx = context()
    # a Spanish file that lacks two strings, as a teacher's half-done file would
    partial = {k: v for k, v in ES.items() if k not in ('ide.run', 'ROSGATE_CAT_LOOPS')}
    ctx.route(re.compile(r'.*/i18n/es\.json$'), lambda route: route.fulfill(
        status=200, content_type='application/json', body=json.dumps(partial)))
    ide = open_ide(ctx, gw, '?lang=es')
    assert ide.page.inner_text('#run') == EN['ide.run'] == '▶ Run'
    assert ide.page.inner_text('#stop') == '■ Detener'
    assert categories(ide)[:2] == ['Lógica', 'Loops']
    # a language offered in languages.json whose file is not there: English everywhere
    ctx2 = context()
    offered = json.loads((ROOT / 'ide/i18n/languages.json').read_text()) | {'eo': {'name': 'Esperanto'}}
    ctx2.route(re.compile(r'.*/i18n/languages\.json$'), lambda route: route.fulfill(
        status=200, content_type='application/json', body=json.dumps(offered)))
    ctx2.route(re.compile(r'.*/i18n/eo\.json$'), lambda route: route.fulfill(status=404, body='no'))
    page = ctx2.new_page()
    page.goto(gw.http_url + '?lang=eo')
    page.wait_for_function("document.body?.dataset.ready === 'true'")
    assert page.evaluate('document.documentElement.lang') == 'eo'
    assert page.inner_text('#run') == '▶ Run'
    assert page.evaluate("[...document.querySelectorAll('#lang option')].map((o) => o.value)") == \
        ['en', 'es', 'de', 'fr', 'pt', 'eo']


def test_the_login_page_follows_lang_and_the_browser(gw):
    def login(query: str = '', **headers) -> str:
        req = urllib.request.Request(gw.http_url + 'login' + query, headers=headers)
        with urllib.request.urlopen(req, timeout=10) as res:
            return res.read().decode()

    assert 'Sign in' in login() and '<html lang="en" dir="ltr">' in login()
    french = login('?lang=fr')
    assert '<html lang="fr"' in french and 'Se connecter' in french and 'Sign in' not in french
    spanish = login(**{'Accept-Language': 'es-MX,es;q=0.9,en;q=0.5'})
    assert 'Iniciar sesión' in spanish and 'Esta pasarela no necesita token.' in spanish
    assert 'Sign in' in login(**{'Accept-Language': 'ja, zh;q=0.8'})          # not offered: English
    assert 'Entrar' in login(**{'Cookie': 'rosgate-lang=pt'})


@pytest.mark.parametrize('lang', ['en', 'es', 'de', 'fr', 'pt'])
def test_the_code_tabs_fit_a_tablet_in_every_language(gw, context, lang):
    """At 1180 px (a tablet) the code panel's tabs stay whole inside it, each on one line: in
    Spanish "ocultar código" once ran out of the panel."""
    ide = open_ide(context(viewport={'width': 1180, 'height': 820}), gw, f'?lang={lang}')
    tabs = ide.js("""() => { const side = document.querySelector('#side').getBoundingClientRect();
      return [...document.querySelectorAll('#side .tabs button')].filter((b) => b.offsetParent).map((b) => {
        const r = b.getBoundingClientRect();
        return { text: b.textContent, inside: r.left >= side.left - 0.5 && r.right <= side.right + 0.5,
                 height: r.height }; }); }""")
    assert len(tabs) == 5, tabs
    assert all(t['inside'] for t in tabs), tabs
    assert all(t['height'] < 1.5 * tabs[0]['height'] for t in tabs), tabs   # one line each, as "Python"


def test_examples_in_the_readers_language(gw, context):
    """An example's title in the menu, its name and its blocks' comments in Spanish, and the
    comments in the generated code; in English as they were written."""
    ide = open_ide(context(), gw, '?lang=es')
    options = ide.page.eval_on_selector_all('#examples option', 'os => os.map((o) => o.textContent)')
    assert 'dibujar un cuadrado (turtlesim)' in options and 'rover PID hacia la meta (rover)' in options, options
    ide.page.select_option('#examples', 'drive_square.json')
    ide.page.wait_for_function("rosgateIde.programName === 'dibujar un cuadrado'")
    comment = ide.js("rosgateIde.workspace.getBlockById('note-1').getCommentText()")
    assert comment == 'Cuatro veces: un lado de 3 y luego un cuarto de vuelta (90°) a la izquierda.', comment
    assert '# Cuatro veces: un lado de 3' in ide.python()
    assert not ide.errors, ide.errors
    english = open_ide(context(), gw, '?lang=en')
    english.page.select_option('#examples', 'pid_goal.json')
    english.page.wait_for_function("rosgateIde.programName === 'rover PID go-to-goal'")
    notes = english.js("rosgateIde.workspace.getAllBlocks(false).map((b) => b.getCommentText()).filter(Boolean)")
    assert 'Until within 10 cm of the goal, every 0.1 s.' in notes, notes
