// The gateway's JSON API (gateway/web/api.py), one helper for every page: a call's answer as JSON (a 204 is
// null), and an error answer thrown as an ApiError carrying the gateway's own words ({"error": ...}), its status
// and its body. A caller that reads a missing route or a refusal as "nothing" catches ApiError (by status where
// it matters); a network failure is thrown as fetch threw it. path: as the page gives it ('api/…' is the page's,
// '/api/…' the gateway's root); query: an object made the URL's query; body: an object sent as JSON.
export class ApiError extends Error {
  constructor(status, message, body = null, statusText = '') {
    super(message);
    this.name = 'ApiError';
    Object.assign(this, { status, body, statusText });
  }
}

export async function api(path, { method = 'GET', body, query, signal } = {}) {
  const url = query ? `${path}${path.includes('?') ? '&' : '?'}${new URLSearchParams(query)}` : path;
  const res = await fetch(url, {
    method, signal, cache: 'no-store', credentials: 'same-origin',
    headers: body === undefined ? {} : { 'Content-Type': 'application/json' },
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  const data = res.status === 204 ? null : await res.json().catch(() => null);
  if (!res.ok) throw new ApiError(res.status, data?.error || `HTTP ${res.status}`, data, res.statusText);
  return data;
}
