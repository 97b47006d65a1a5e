// The sessions list and the form that creates a session from a JSON body (typed or uploaded).

import { api, rememberToken } from './api.js';

const cell = (text) => {
  const td = document.createElement('td');
  td.textContent = text;
  return td;
};

/** Renders `sessions` into the table; the demo session (if any) is marked. */
export function renderSessions(tbody, empty, sessions, demoId) {
  tbody.replaceChildren(
    ...sessions.map((s) => {
      const tr = document.createElement('tr');
      tr.dataset.session = s.id;
      if (s.id === demoId) tr.className = 'demo';
      const open = document.createElement('a');
      open.href = `#/session/${s.id}`;
      open.textContent = 'open';
      const td = document.createElement('td');
      td.append(open);
      tr.append(cell(s.id), cell(s.name || ''), cell(s.state), cell(String(s.clients)), cell(`${s.next_sample}`), td);
      return tr;
    }),
  );
  empty.hidden = sessions.length > 0;
}

/** Wires the create form: a chosen file fills the text area; submit posts it. */
export function wireCreateForm({ form, file, body, result }, onCreated) {
  file.addEventListener('change', async () => {
    const f = file.files?.[0];
    if (f) body.value = await f.text();
  });
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    try {
      JSON.parse(body.value);
    } catch (err) {
      result.textContent = `not JSON: ${err.message}`;
      return;
    }
    try {
      const created = await api.createSession(body.value);
      rememberToken(created.id, created.token);
      result.textContent = `created ${created.id}`;
      result.dataset.created = created.id;
      onCreated(created);
    } catch (err) {
      result.textContent = `refused: ${err.message}${err.field ? ` (${err.field})` : ''}`;
    }
  });
}
