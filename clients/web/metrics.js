// The session's metrics (GET /v1/sessions/{id}/metrics), polled once a second.

import { api } from './api.js';

const ms = (v) => `${v.toFixed(1)} ms`;

// Each tracker sensor's false measurements per scan as the tracker estimates them, with the
// configured rate (the floor) in brackets: an estimate far above it is a noisy detector.
// Sensors that never reported (an array's positions when its directions are used) are left out.
const clutter = (list) => {
  const seen = list.filter((c) => c.scans > 0);
  return seen.length
    ? seen.map((c) => `${c.sensor} ${c.estimated.toFixed(1)} (${c.configured})`).join(', ')
    : 'none';
};

function rows(m) {
  const refused = Object.entries(m.refused);
  const refusedTotal = refused.reduce((s, [, n]) => s + n, 0);
  return [
    ['state', m.state],
    ['steps', m.steps],
    ['audio processed', `${m.audio_s.toFixed(1)} s`],
    ['real-time factor', m.real_time_factor.toFixed(3)],
    ['step latency p50 / p95 / p99', `${ms(m.step_latency_ms.p50)} / ${ms(m.step_latency_ms.p95)} / ${ms(m.step_latency_ms.p99)}`],
    ['step processing p50 / p95', `${ms(m.step_processing_ms.p50)} / ${ms(m.step_processing_ms.p95)}`],
    ['dropped input', refusedTotal ? `${refusedTotal} (${refused.map(([k, n]) => `${k} ${n}`).join(', ')})` : '0'],
    ['output dropped', m.output_dropped],
    ['queue', `${m.queue_depth} / ${m.queue_capacity}`],
    ['live tracks / labels', `${m.live_tracks} / ${m.labels_total}`],
    ['false detections per scan (configured)', clutter(m.clutter ?? [])],
    ['clients', m.clients],
  ];
}

export class MetricsPanel {
  constructor(dl, sessionId) {
    this.dl = dl;
    this.id = sessionId;
    this.timer = setInterval(() => this.refresh(), 1000);
    this.refresh();
  }

  async refresh() {
    try {
      const m = await api.metrics(this.id);
      this.dl.replaceChildren(
        ...rows(m).flatMap(([k, v]) => {
          const dt = document.createElement('dt');
          dt.textContent = k;
          const dd = document.createElement('dd');
          dd.textContent = String(v);
          dd.dataset.metric = k;
          return [dt, dd];
        }),
      );
    } catch (e) {
      this.dl.textContent = `metrics unavailable: ${e.message}`;
    }
  }

  close() {
    clearInterval(this.timer);
  }
}
