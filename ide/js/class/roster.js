// The class view's roster: every member of the LMS courses and their role, as the LMS lists them
// (LTI Advantage NRPS, read by the gateway at each launch of the course: GET api/roster), so the
// teacher sees the whole class before a student first launches; "Refresh" reads it again now
// (POST api/roster). A member who left the course is marked (the gateway no longer lets them book).
import { t } from '../i18n.js';
import { api } from '../link/api.js';

const rosterApi = (method) => api('api/roster', { method });

function memberItem(m) {
  const left = m.status !== 'Active';
  const li = Object.assign(document.createElement('li'), {
    textContent: `${m.name} · ${t(`role.${m.role}`)}${left ? ` · ${t('class.roster.left')}` : ''}`,
    title: `${m.title} · ${m.roles}`,
  });
  Object.assign(li.dataset, { person: m.person, role: m.role, status: m.status });
  return li;
}

export function mountRoster(section) {
  const list = section.querySelector('ul');
  const state = section.querySelector('.roster-state');
  const show = (body) => {
    const members = body?.members ?? [];
    list.replaceChildren(...members.map(memberItem));
    section.hidden = !body?.enabled && !members.length;
    state.textContent = members.length ? t('class.roster.members', { n: members.length }) : t('class.roster.none');
    if (Object.keys(body?.failed ?? {}).length) state.textContent += ` · ${t('class.roster.failed')}`;
    section.dataset.members = String(members.length);
  };
  const load = (method) => rosterApi(method).then(show).catch(() => { if (method === 'POST') state.textContent = t('class.roster.failed'); });
  section.querySelector('.roster-refresh').onclick = () => load('POST');
  return () => load('GET');
}
