// The class view's exercise results: for each student, their best and last attempt per exercise
// (GET api/exercise-results: an admin's answer holds the class's; a student's, their own), shown on
// their station's tile with a "passed" mark, the score and the program as it ran. The gateway
// checked each attempt on the robot's own topics (gateway/exercises), not on what a page said.
import { t } from './i18n.js';

export async function exerciseSummary() {
  const res = await fetch('api/exercise-results?summary=1', { cache: 'no-store' });   // not every attempt's program
  const body = await res.json().catch(() => null);
  if (!res.ok) throw new Error(body?.error || `HTTP ${res.status}`);
  return body.summary;
}

const pct = (score) => `${Math.round(score * 100)}%`;

function attemptLine(key, row) {
  const when = new Date(row.ended_at * 1000).toLocaleTimeString();
  return t(key, { score: pct(row.score), when, result: t(row.passed ? 'class.ex.passed' : 'class.ex.failed') });
}

// One entry: "✓ title · best 100% · last 50% (n attempts)", the program of the best attempt underneath.
export function exerciseItem(entry) {
  const li = document.createElement('li');
  li.dataset.exercise = entry.exercise;
  li.toggleAttribute('data-passed', Boolean(entry.best.passed));
  const mark = Object.assign(document.createElement('b'), {
    className: 'mark', textContent: entry.best.passed ? '✓' : '✗',
    title: t(entry.best.passed ? 'class.ex.passed' : 'class.ex.failed'),
  });
  const text = document.createElement('span');
  text.textContent = `${entry.exercise} · ${attemptLine('class.ex.best', entry.best)} · ${attemptLine('class.ex.last', entry.last)} · ${t('class.ex.attempts', { n: entry.attempts })}`;
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
