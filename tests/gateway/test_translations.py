"""The translation files (ide/i18n/) against the pages and the code that name their keys: every key
a page, a script, the toolbox or a block definition uses is in English; every English key is in
every offered language, with the same placeholders; no page word is left outside a data-i18n
element. A file-level check, so that a string added in English only fails here, not in a class."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest

from gateway.web.language import Texts, accepted, best

IDE = Path(__file__).resolve().parents[2] / 'ide'
I18N = IDE / 'i18n'
PAGES = sorted(IDE.glob('*.html'))
LANGUAGES = json.loads((I18N / 'languages.json').read_text())
ENGLISH = json.loads((I18N / 'en.json').read_text())
ATTRS = ('title', 'placeholder', 'aria-label')
# words that are the same in every language: names, units, symbols
SAME = {'rosgate', 'Twist', 'TwistStamped', 'Hz', 'Python', 'JavaScript', '.py', '3D', '↻', '▲', '▼', '◀', '▶', '■',
        '…', '–', '5', '10', '20'}


class Words(HTMLParser):
    """Keys a page names, and its words outside any data-i18n element."""

    VOID = {'input', 'br', 'img', 'link', 'meta', 'source'}

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.keys: list[str] = []
        self.loose: list[str] = []
        self.stack: list[tuple[str, bool]] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for attr in ATTRS:
            if a.get(f'data-i18n-{attr}'):
                self.keys.append(a[f'data-i18n-{attr}'])
            elif a.get(attr) and attr != 'placeholder' and re.search('[A-Za-z]{2}', a[attr]):
                self.loose.append(f'{tag}[{attr}]={a[attr]!r}')
        if a.get('data-i18n'):
            self.keys.append(a['data-i18n'])
        if tag not in self.VOID:
            # data-i18n-js: a script writes this element's words (in the reader's language)
            self.stack.append((tag, 'data-i18n' in a or 'data-i18n-js' in a or tag in ('script', 'style')))

    def handle_endtag(self, tag):
        if tag not in self.VOID and self.stack:
            self.stack.pop()

    def handle_data(self, data):
        text = data.strip()
        if text and text not in SAME and re.search('[A-Za-z]', text) and not any(t for _, t in self.stack):
            self.loose.append(repr(text))


def page_words(page: Path) -> Words:
    w = Words()
    w.feed(page.read_text())
    return w


def code_keys() -> set[str]:
    """Keys the scripts pass to t() / tn() as literals, and the %{BKY_...} references."""
    keys = set()
    for js in (IDE / 'js').rglob('*.js'):   # the pages' parts in folders (js/inspect/) too
        text = js.read_text()
        for m in re.finditer(r"\bt\(\s*'([^'$]+)'", text):
            keys.add(m.group(1))
        for m in re.finditer(r"\bt\(\s*[^()]*?\?\s*'([^']+)'\s*:\s*'([^']+)'", text):
            keys.update(m.groups())
        for m in re.finditer(r"\btn\(\s*'([^']+)'", text):
            keys.update({m.group(1) + '.one', m.group(1) + '.other'})
    for f in [IDE / 'toolbox.json', *(IDE / 'blocks').glob('*.json')]:
        keys.update(re.findall(r'%\{BKY_(ROSGATE_\w+)\}', f.read_text()))
    return keys


# Where a script writes words the reader sees: an element's text or title, an attribute, the
# console's lines, the twin's notices, a mesh's problem, a Python run's failure, an innerHTML.
SHOWN = re.compile(r"""(?:\.(?:textContent|title|alt|placeholder)\s*=|setAttribute\(\s*'(?:title|aria-label|alt|placeholder)'\s*,"""
                   r"""|\.(?:info|error|warn)\(|\b(?:notice|onState|onProblem|fail)\(|innerHTML\s*=)\s*(?=['`])""")
CODE_NAMES = {'rosapi', 'Python', 'JavaScript'}


def literal(text: str, i: int) -> str:
    """The words of the string literal opening at text[i] ('...' or a template), without what a
    template interpolates (${...}, nested templates and all)."""
    quote, out, depth, j = text[i], [], 0, i + 1
    while j < len(text):
        c = text[j]
        if c == '\\':
            j += 2
            continue
        if depth == 0:
            if c == quote:
                break
            if quote == '`' and text.startswith('${', j):
                depth, j = 1, j + 2
                continue
            out.append(c)
        elif c == '{':
            depth += 1
        elif c == '}':
            depth -= 1
        elif c == '`':                       # a template inside the interpolation: skip it whole
            j = text.index('`', j + 1)
        j += 1
    return ''.join(out)


def test_no_script_writes_english_words_outside_t():
    """Words a script shows (an element's text or title, the console's statuses, the twin's
    notices) come from t(): a literal with words there is English in every language."""
    loose = []
    for js in sorted((IDE / 'js').rglob('*.js')):
        text = js.read_text()
        for m in SHOWN.finditer(text):
            words = re.sub(r'<[^>]*>', ' ', literal(text, m.end()))
            if [w for w in re.findall(r'[A-Za-z]{3,}', words) if w not in CODE_NAMES]:
                loose.append(f'{js.name}: {text[m.start():m.end() + 60]!r}')
    assert not loose, f'words written by scripts outside t(): {loose}'


def placeholders(text: str) -> set[str]:
    return set(re.findall(r'\{\w+\}|%\d', text))


def test_every_key_the_pages_and_scripts_name_is_in_english():
    named = {k for page in PAGES for k in page_words(page).keys} | code_keys()
    assert len(named) > 300
    missing = sorted(named - set(ENGLISH))
    assert not missing, f'keys used but not in en.json: {missing}'


def test_no_page_word_is_left_untranslated():
    for page in PAGES:
        loose = page_words(page).loose
        assert not loose, f'{page.name}: words outside data-i18n: {loose}'


def test_the_pages_static_english_is_en_json():
    """A page's own English is en.json's, so a page shown in English says the same before and
    after i18n.js runs."""
    for page in PAGES:
        text = page.read_text()
        for m in re.finditer(r'data-i18n="([^"]+)"[^>]*>([^<]*)<', text):
            assert ENGLISH[m.group(1)] == m.group(2).strip().replace('&amp;', '&'), (page.name, m.group(1))


@pytest.mark.parametrize('lang', [code for code in LANGUAGES if code != 'en'])
def test_every_language_has_every_english_key_with_its_placeholders(lang):
    texts = json.loads((I18N / f'{lang}.json').read_text())
    assert sorted(set(ENGLISH) - set(texts)) == [], f'{lang}.json lacks these keys'
    assert sorted(set(texts) - set(ENGLISH)) == [], f'{lang}.json has keys English does not'
    for key, value in texts.items():
        assert isinstance(value, str) and value.strip(), (lang, key)
        assert placeholders(value) == placeholders(ENGLISH[key]), (lang, key, value)
    # translated, not copied: most strings differ from English (names and units may not)
    same = [k for k in ENGLISH if texts[k] == ENGLISH[k]]
    assert len(same) < 0.15 * len(ENGLISH), (lang, same)


def test_the_gateway_picks_a_language_and_falls_back_to_english(tmp_path):
    assert accepted('fr-CH, fr;q=0.9, en;q=0.8, de;q=0.7, *;q=0.5') == ['fr-CH', 'fr', 'en', 'de']
    assert accepted('de;q=0, es') == ['es']
    assert best(['pt-BR'], ['en', 'pt']) == 'pt'
    assert best(['xx', None, 'es-ES'], ['en', 'es']) == 'es'
    assert best(['xx'], ['en']) is None
    (tmp_path / 'languages.json').write_text('{"en": {"name": "English"}, "eo": {"name": "Esperanto"}}')
    (tmp_path / 'en.json').write_text('{"a": "hello {name}", "b": "only English"}')
    (tmp_path / 'eo.json').write_text('{"a": "saluton {name}"}')
    texts = Texts(tmp_path)
    assert texts.offered() == ['en', 'eo']
    assert texts.get('eo', 'a', name='Ada') == 'saluton Ada'
    assert texts.get('eo', 'b') == 'only English'                  # a missing string: English
    assert texts.get('xx', 'a', name='Bo') == 'hello Bo'           # a missing language: English
    assert texts.get('eo', 'nowhere') == 'nowhere'
