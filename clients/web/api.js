// REST calls and the credentials the dashboard holds for this tab (sessionStorage): the admin
// key, when the server has one, and each session's token (from creation, the demo, or typed in).

const ADMIN_KEY = 'avsep.adminKey';
const TOKENS = 'avsep.tokens';

export class ApiError extends Error {
  constructor(status, body) {
    super(body?.error?.message || `HTTP ${status}`);
    this.status = status;
    this.code = body?.error?.code;
    this.field = body?.error?.field;
  }
}

export function adminKey() {
  return sessionStorage.getItem(ADMIN_KEY) || '';
}

export function setAdminKey(key) {
  sessionStorage.setItem(ADMIN_KEY, key);
}

function tokens() {
  try {
    return JSON.parse(sessionStorage.getItem(TOKENS) || '{}');
  } catch {
    return {};
  }
}

/** The credential that opens session `id`: its token, else the admin key. */
export function tokenFor(id) {
  return tokens()[id] || adminKey();
}

export function rememberToken(id, token) {
  const all = tokens();
  all[id] = token;
  sessionStorage.setItem(TOKENS, JSON.stringify(all));
}

async function request(method, path, { bearer = '', body } = {}) {
  const headers = {};
  if (bearer) headers.Authorization = `Bearer ${bearer}`;
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  const res = await fetch(path, { method, headers, body });
  const text = await res.text();
  let json = null;
  try {
    json = text ? JSON.parse(text) : null;
  } catch {
    json = null;
  }
  if (!res.ok) throw new ApiError(res.status, json);
  return json;
}

const enc = encodeURIComponent;

export const api = {
  listSessions: () => request('GET', '/v1/sessions', { bearer: adminKey() }),
  /** `body` is the JSON text of a POST /v1/sessions body. */
  createSession: (body) => request('POST', '/v1/sessions', { bearer: adminKey(), body }),
  session: (id) => request('GET', `/v1/sessions/${enc(id)}`, { bearer: tokenFor(id) }),
  metrics: (id) => request('GET', `/v1/sessions/${enc(id)}/metrics`, { bearer: tokenFor(id) }),
  detections: (id) =>
    request('GET', `/dashboard/api/sessions/${enc(id)}/detections`, { bearer: tokenFor(id) }),
  demo: () => request('GET', '/dashboard/api/demo', { bearer: adminKey() }),
  /** Browsers cannot set headers on a WebSocket: the token goes in the query. */
  streamUrl(id) {
    const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
    return `${scheme}//${location.host}/v1/sessions/${enc(id)}/stream?token=${enc(tokenFor(id))}`;
  },
};
