// The dashboard: a sessions list (#/) and a live view of one session (#/session/<id>).
// Messages update the live state; drawing happens once per animation frame.

import { api, adminKey, setAdminKey, rememberToken, tokenFor } from './api.js';
import { renderSessions, wireCreateForm } from './sessions.js';
import { LiveState } from './live.js';
import { openStream } from './stream.js';
import { RoomMap } from './roommap.js';
import { CameraPanel } from './camera.js';
import { AudioBank } from './audio.js';
import { MetricsPanel } from './metrics.js';

const $ = (id) => document.getElementById(id);
const DETECTIONS_PERIOD_MS = 125;

// Read by the browser test (tests/dashboard/): the live state and sample counters.
window.avsep = { live: null, audioSamples: {}, demo: null };

let listTimer = null;
let live = null; // the open live view

async function findDemo() {
  try {
    const d = await api.demo();
    rememberToken(d.id, d.token);
    window.avsep.demo = d.id;
    return d.id;
  } catch {
    return null;
  }
}

async function refreshList() {
  try {
    const [list, demoId] = await Promise.all([api.listSessions(), findDemo()]);
    renderSessions($('sessions').tBodies[0], $('sessions-empty'), list.sessions, demoId);
    $('status').textContent = `${list.sessions.length} session(s)`;
  } catch (e) {
    $('status').textContent = `cannot list sessions: ${e.message}`;
  }
}

function showList() {
  closeLive();
  $('live-view').hidden = true;
  $('list-view').hidden = false;
  refreshList();
  listTimer = setInterval(refreshList, 2000);
}

class LiveView {
  constructor(id) {
    this.id = id;
    this.closed = false;
    this.ws = null;
    this.parts = [];
    $('live-title').textContent = `session ${id}`;
    $('live-token').value = tokenFor(id);
    // The previous session's state and panels must not show while this one loads.
    $('live-state').textContent = 'loading…';
    $('cameras').replaceChildren();
    this.start();
  }

  async start() {
    let info;
    try {
      info = await api.session(this.id);
    } catch (e) {
      $('live-state').textContent = `${e.message} — enter the session's token and connect`;
      return;
    }
    if (this.closed) return;
    $('live-title').textContent = `${info.name || 'session'} ${info.id}`;
    this.state = new LiveState(info);
    window.avsep.live = this.state;
    this.map = new RoomMap($('room'), info);
    $('cameras').replaceChildren();
    this.cameras = new CameraPanel($('cameras'), info.cameras);
    $('players').replaceChildren();
    this.audio = new AudioBank($('players'), info.sample_rate);
    window.avsep.audioSamples = this.audio.samples;
    $('audio-enable').onclick = () => this.audio.enable();
    this.metrics = new MetricsPanel($('metrics'), this.id);
    this.detTimer = info.cameras.length ? setInterval(() => this.pollDetections(), DETECTIONS_PERIOD_MS) : null;
    this.connect();
    const frame = (now) => {
      if (this.closed) return;
      this.draw(now);
      requestAnimationFrame(frame);
    };
    requestAnimationFrame(frame);
  }

  connect() {
    this.ws?.close();
    $('live-state').textContent = 'connecting…';
    this.ws = openStream(api.streamUrl(this.id), {
      message: (m) => this.onMessage(m),
      audio: (f) => this.audio.push(f),
      close: (e) => {
        if (this.closed) return;
        $('live-state').textContent = `stream closed (${e.code}${e.reason ? `: ${e.reason}` : ''})`;
        // An abnormal close (server restart, network) retries; a finished session does not.
        if (e.code !== 1000 && e.code !== 1001) setTimeout(() => !this.closed && this.connect(), 2000);
      },
    });
  }

  onMessage(m) {
    switch (m.type) {
      case 'welcome':
        $('live-state').textContent = `streaming · ${m.sample_rate} Hz · ${m.channels} channels · step ${(m.step_s * 1000).toFixed(0)} ms`;
        break;
      case 'tracks':
        this.state.applyTracks(m);
        break;
      case 'error':
        $('live-state').textContent = `error: ${m.error.message}`;
        break;
      default:
        break;
    }
  }

  async pollDetections() {
    if (this.polling) return;
    this.polling = true;
    try {
      this.state.applyDetections(await api.detections(this.id));
    } catch {
      // The session may have ended; the stream's close says so.
    } finally {
      this.polling = false;
    }
  }

  draw(now) {
    this.audio.draw();
    if (!this.state.dirty && !this.anySpeaking()) return;
    this.state.dirty = false;
    this.map.draw(this.state, now);
    this.cameras.draw(this.state);
    this.audio.markLive(new Set([...this.state.tracks.values()].filter((t) => t.live).map((t) => t.label)));
  }

  anySpeaking() {
    for (const t of this.state.tracks.values()) if (t.live && t.speaking > 0.5) return true;
    return false;
  }

  close() {
    this.closed = true;
    this.ws?.close();
    this.metrics?.close();
    this.audio?.close();
    clearInterval(this.detTimer);
  }
}

function closeLive() {
  clearInterval(listTimer);
  live?.close();
  live = null;
}

function route() {
  const m = location.hash.match(/^#\/session\/([^/]+)$/);
  if (!m) return showList();
  closeLive();
  $('list-view').hidden = true;
  $('live-view').hidden = false;
  live = new LiveView(decodeURIComponent(m[1]));
}

$('admin-key').value = adminKey();
$('admin-key').addEventListener('change', (e) => {
  setAdminKey(e.target.value.trim());
  route();
});
$('live-connect').addEventListener('click', () => {
  const id = live?.id;
  if (!id) return;
  rememberToken(id, $('live-token').value.trim());
  route();
});
wireCreateForm(
  { form: $('create-form'), file: $('create-file'), body: $('create-body'), result: $('create-result') },
  (created) => {
    window.avsep.created = created.id;
    refreshList();
  },
);
window.addEventListener('hashchange', route);
route();
