// One player per label: separated audio chunks are counted and metered as they arrive, and,
// once the user enables sound (browsers start audio only after a gesture), scheduled back to
// back on a WebAudio clock with a short jitter buffer.

import { labelColor } from './labels.js';

const LEAD_S = 0.15; // jitter buffer
const MAX_LEAD_S = 1.0; // past this the schedule is reset (after a stall)
const METER_FLOOR_DB = -60;

export class AudioBank {
  constructor(container, sampleRate) {
    this.container = container;
    this.sampleRate = sampleRate;
    this.players = new Map();
    this.ctx = null;
    this.samples = {}; // label -> samples received (for tests and the UI)
  }

  /** Starts playback (call from a user gesture). */
  enable() {
    if (!this.ctx) this.ctx = new AudioContext();
    this.ctx.resume();
    for (const p of this.players.values()) this.connect(p);
  }

  connect(p) {
    if (!this.ctx || p.gain) return;
    p.gain = this.ctx.createGain();
    p.gain.gain.value = p.toggle.checked ? 1 : 0;
    p.gain.connect(this.ctx.destination);
  }

  add(label) {
    const el = document.createElement('div');
    el.className = 'player';
    el.dataset.label = label;
    el.dataset.samples = '0';
    const name = document.createElement('label');
    name.className = 'swatch';
    name.style.color = labelColor(label);
    const toggle = document.createElement('input');
    toggle.type = 'checkbox';
    toggle.checked = true;
    toggle.title = 'play this voice';
    name.append(toggle, ` ${label}`);
    const meter = document.createElement('meter');
    meter.min = METER_FLOOR_DB;
    meter.max = 0;
    meter.low = -30;
    meter.high = -6;
    meter.value = METER_FLOOR_DB;
    const db = document.createElement('span');
    db.className = 'muted';
    el.append(name, meter, db);
    this.container.append(el);
    const p = { label, el, toggle, meter, db, level: 0, next: 0, gain: null, samples: 0 };
    toggle.onchange = () => {
      if (p.gain) p.gain.gain.value = toggle.checked ? 1 : 0;
    };
    this.connect(p);
    this.players.set(label, p);
    return p;
  }

  push(frame) {
    const p = this.players.get(frame.label) || this.add(frame.label);
    const x = frame.samples;
    let sum = 0;
    for (let i = 0; i < x.length; i++) sum += x[i] * x[i];
    const rms = Math.sqrt(sum / Math.max(1, x.length));
    p.level = Math.max(rms, p.level);
    p.samples += x.length;
    this.samples[frame.label] = p.samples;
    p.el.dataset.samples = String(p.samples);
    if (this.ctx && this.ctx.state === 'running' && p.gain && x.length) this.schedule(p, x);
  }

  schedule(p, x) {
    const buf = this.ctx.createBuffer(1, x.length, this.sampleRate);
    buf.copyToChannel(x, 0);
    const src = this.ctx.createBufferSource();
    src.buffer = buf;
    src.connect(p.gain);
    const now = this.ctx.currentTime;
    if (p.next < now + 0.02 || p.next > now + MAX_LEAD_S) p.next = now + LEAD_S;
    src.start(p.next);
    p.next += buf.duration;
  }

  /** Marks players whose track has ended. */
  markLive(liveLabels) {
    for (const [label, p] of this.players) p.el.classList.toggle('ended', !liveLabels.has(label));
  }

  /** Meters, once per animation frame: the peak RMS since the last frame, then decay. */
  draw() {
    for (const p of this.players.values()) {
      const db = p.level > 0 ? Math.max(METER_FLOOR_DB, 20 * Math.log10(p.level)) : METER_FLOOR_DB;
      p.meter.value = db;
      p.db.textContent = `${db.toFixed(0)} dB`;
      p.level *= 0.85;
    }
  }

  close() {
    this.ctx?.close();
  }
}
