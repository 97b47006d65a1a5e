// Top-down room map: the region, 1 m grid, microphone arrays, cameras with their horizontal
// field of view, and the tracks with trails and a speaking ring. x to the right, y up.

import { labelColor } from './labels.js';
import { cameraGeometry } from './camera.js';

const FOV_LENGTH_M = 3;

function bounds(info) {
  if (info.region) {
    return { x0: info.region.min[0], y0: info.region.min[1], x1: info.region.max[0], y1: info.region.max[1] };
  }
  const pts = info.arrays.flatMap((a) => a.mics);
  for (const c of info.cameras) {
    const g = cameraGeometry(c);
    if (g) pts.push(g.centre);
  }
  const xs = pts.map((p) => p[0]);
  const ys = pts.map((p) => p[1]);
  const pad = 3;
  return { x0: Math.min(...xs) - pad, y0: Math.min(...ys) - pad, x1: Math.max(...xs) + pad, y1: Math.max(...ys) + pad };
}

export class RoomMap {
  constructor(canvas, info) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.info = info;
    const b = bounds(info);
    const m = 0.4; // margin (m)
    this.view = { x0: b.x0 - m, y0: b.y0 - m, x1: b.x1 + m, y1: b.y1 + m };
    this.region = b;
    this.cameras = info.cameras.map(cameraGeometry).filter(Boolean);
    const w = this.view.x1 - this.view.x0;
    const h = this.view.y1 - this.view.y0;
    canvas.width = 720;
    canvas.height = Math.max(240, Math.round((720 * h) / w));
    this.scale = Math.min(canvas.width / w, canvas.height / h);
  }

  px(p) {
    return [(p[0] - this.view.x0) * this.scale, this.canvas.height - (p[1] - this.view.y0) * this.scale];
  }

  drawStatic(ctx) {
    const { x0, y0, x1, y1 } = this.region;
    ctx.strokeStyle = '#243042';
    ctx.lineWidth = 1;
    ctx.beginPath();
    for (let x = Math.ceil(x0); x <= x1; x++) {
      ctx.moveTo(...this.px([x, y0]));
      ctx.lineTo(...this.px([x, y1]));
    }
    for (let y = Math.ceil(y0); y <= y1; y++) {
      ctx.moveTo(...this.px([x0, y]));
      ctx.lineTo(...this.px([x1, y]));
    }
    ctx.stroke();
    ctx.strokeStyle = '#55657a';
    const [ax, ay] = this.px([x0, y1]);
    const [bx, by] = this.px([x1, y0]);
    ctx.strokeRect(ax, ay, bx - ax, by - ay);
    for (const cam of this.cameras) {
      const c = this.px(cam.centre);
      const l = this.px(cam.centre.map((v, i) => v + FOV_LENGTH_M * cam.left[i]));
      const r = this.px(cam.centre.map((v, i) => v + FOV_LENGTH_M * cam.right[i]));
      ctx.fillStyle = 'rgba(79,163,255,0.08)';
      ctx.strokeStyle = 'rgba(79,163,255,0.6)';
      ctx.beginPath();
      ctx.moveTo(...c);
      ctx.lineTo(...l);
      ctx.lineTo(...r);
      ctx.closePath();
      ctx.fill();
      ctx.stroke();
      ctx.fillStyle = '#4fa3ff';
      ctx.fillRect(c[0] - 5, c[1] - 5, 10, 10);
      ctx.fillText(cam.id, c[0] + 8, c[1] + 4);
    }
    for (const a of this.info.arrays) {
      ctx.fillStyle = '#c7d0dc';
      for (const m of a.mics) {
        const p = this.px(m);
        ctx.beginPath();
        ctx.arc(p[0], p[1], 2.5, 0, 2 * Math.PI);
        ctx.fill();
      }
      const c = a.mics.reduce((s, m) => s.map((v, i) => v + m[i] / a.mics.length), [0, 0, 0]);
      const p = this.px(c);
      ctx.fillText(a.id, p[0] + 8, p[1] + 14);
    }
  }

  draw(state, now) {
    const ctx = this.ctx;
    ctx.fillStyle = '#0b0e13';
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.font = '12px system-ui';
    this.drawStatic(ctx);
    for (const tr of state.visibleTracks()) {
      if (tr.trail.length > 1) {
        ctx.strokeStyle = labelColor(tr.label, 0.45 * tr.alpha);
        ctx.lineWidth = 2;
        ctx.beginPath();
        ctx.moveTo(...this.px(tr.trail[0]));
        for (const p of tr.trail) ctx.lineTo(...this.px(p));
        ctx.stroke();
      }
      const p = this.px(tr.position);
      if (tr.live && tr.speaking > 0.5) {
        const pulse = 1 + 0.25 * Math.sin(now / 120);
        ctx.strokeStyle = labelColor(tr.label, 0.8);
        ctx.lineWidth = 2;
        ctx.beginPath();
        ctx.arc(p[0], p[1], (10 + 8 * tr.speaking) * pulse, 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.fillStyle = labelColor(tr.label, tr.alpha);
      ctx.beginPath();
      ctx.arc(p[0], p[1], 7, 0, 2 * Math.PI);
      ctx.fill();
      ctx.fillText(`${tr.label}${tr.live ? '' : ' (ended)'}`, p[0] + 10, p[1] - 8);
    }
    ctx.fillStyle = '#8a94a3';
    ctx.fillText(`step ${state.step}  t ${state.t.toFixed(2)} s  ${[...state.tracks.values()].filter((t) => t.live).length} tracks`, 8, 16);
  }
}
