// The class view's exercise results: for each student, their best and last attempt per exercise
// (GET api/exercise-results: an admin's answer holds the class's; a student's, their own), shown by
// person in the page's Attempts section (whatever the set-up: one robot or a fleet, signed in by
// LTI or a token, or browsers without sign-in: each attempt names its person's key), and on the
// tile of the station its student owns now, with a "passed" mark, the score, the program as it ran
// and its replay. The gateway checked each attempt on the robot's own topics (gateway/exercises),
// not on what a page said.
import { t, localized } from '../i18n.js';
import { api } from '../link/api.js';

export async function exerciseSummary() {
  return (await api('api/exercise-results', { query: { summary: 1 } })).summary;   // not every attempt's program
}

const pct = (score) => `${Math.round(score * 100)}%`;

function attemptLine(key, row) {
  const when = new Date(row.ended_at * 1000).toLocaleTimeString();
  return t(key, { score: pct(row.score), when, result: t(row.passed ? 'class.ex.passed' : 'class.ex.failed') });
}

// One entry: "✓ title · best 100% · last 50% (n attempts)", the program of the best attempt underneath.
export function exerciseItem(entry, titles = {}) {
  const li = document.createElement('li');
  li.dataset.exercise = entry.exercise;
  li.toggleAttribute('data-passed', Boolean(entry.best.passed));
  const mark = Object.assign(document.createElement('b'), {
    className: 'mark', textContent: entry.best.passed ? '✓' : '✗',
    title: t(entry.best.passed ? 'class.ex.passed' : 'class.ex.failed'),
  });
  const text = document.createElement('span');
  text.textContent = `${titles[entry.exercise] ?? entry.exercise} · ${attemptLine('class.ex.best', entry.best)} · ${attemptLine('class.ex.last', entry.last)} · ${t('class.ex.attempts', { n: entry.attempts })}`;
  const details = document.createElement('details');
  details.append(Object.assign(document.createElement('summary'), { textContent: t('class.ex.program') }),
    Object.assign(document.createElement('pre'), { textContent: entry.best.program }));
  li.append(mark, ' ', text, details);
  if (entry.best.recording) {
    li.append(' ', Object.assign(document.createElement('a'), {
      href: `api/recordings/${encodeURIComponent(entry.best.recording)}.mcap`, textContent: t('class.ex.replay'),
    }));
  }
  return li;
}

// The exercises' titles in the reader's language, by id ({} when none can be read).
export async function exerciseTitles() {
  try {
    return Object.fromEntries((await api('api/exercises')).exercises.map((e) => [e.id, localized(e.titles && Object.keys(e.titles).length ? { en: e.title, ...e.titles } : e.title)]));
  } catch { return {}; }
}

// Every person's attempts (the summary of api/exercise-results), by person: their name (and, where
// two people share one, which sign-in or browser), then each exercise's best and last attempt.
export function showAttempts(section, summary, titles = {}) {
  const people = new Map();
  for (const entry of summary) {
    if (!people.has(entry.person)) people.set(entry.person, { name: entry.name, entries: [] });
    people.get(entry.person).entries.push(entry);
  }
  const names = new Map();
  for (const p of people.values()) names.set(p.name, (names.get(p.name) ?? 0) + 1);
  const rows = [...people].sort(([, a], [, b]) => a.name.localeCompare(b.name)).map(([key, p]) => {
    const el = document.createElement('article');
    el.className = 'person';
    el.dataset.person = key;
    el.dataset.passed = String(p.entries.filter((e) => e.best.passed).length);
    const h = document.createElement('h4');
    h.textContent = names.get(p.name) > 1 ? `${p.name} (${key.slice(0, 14)})` : p.name;
    const list = document.createElement('ul');
    list.className = 'exercises';
    list.setAttribute('aria-label', t('class.ex.label'));
    list.replaceChildren(...p.entries.map((e) => exerciseItem(e, titles)));
    el.append(h, list);
    return el;
  });
  section.querySelector('.people').replaceChildren(...rows);
  section.hidden = !rows.length;
  section.dataset.people = String(rows.length);
}
