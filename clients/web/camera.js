// Camera geometry from a 3x4 projection matrix P = [M | p4] (lens distortion, when the
// calibration has one, is not drawn), and the camera panel: the latest detections and the
// tracks projected into each image.

import { labelColor } from './labels.js';

function inv3(m) {
  const [a, b, c] = m[0];
  const [d, e, f] = m[1];
  const [g, h, i] = m[2];
  const A = e * i - f * h;
  const B = -(d * i - f * g);
  const C = d * h - e * g;
  const det = a * A + b * B + c * C;
  if (Math.abs(det) < 1e-12) return null;
  return [
    [A / det, -(b * i - c * h) / det, (b * f - c * e) / det],
    [B / det, (a * i - c * g) / det, -(a * f - c * d) / det],
    [C / det, -(a * h - b * g) / det, (a * e - b * d) / det],
  ];
}

const mul3 = (m, v) => m.map((r) => r[0] * v[0] + r[1] * v[1] + r[2] * v[2]);

/** Pixel of world point `x` (metres), or null when it is behind the camera. */
export function project(P, x) {
  const [u, v, w] = P.map((r) => r[0] * x[0] + r[1] * x[1] + r[2] * x[2] + r[3]);
  return w > 1e-9 ? [u / w, v / w, w] : null;
}

/** Centre and the viewing rays through the image's left and right edges (mid-height). */
export function cameraGeometry(cam) {
  const P = cam.projection;
  if (!P) return null;
  const M = P.map((r) => r.slice(0, 3));
  const Mi = inv3(M);
  if (!Mi) return null;
  const centre = mul3(Mi, P.map((r) => -r[3]));
  // A point C + s d with s > 0 projects in front of the camera (w = s).
  const ray = (u, v) => {
    const d = mul3(Mi, [u, v, 1]);
    const n = Math.hypot(...d) || 1;
    return d.map((x) => x / n);
  };
  return {
    id: cam.id,
    centre,
    left: ray(0, cam.height / 2),
    right: ray(cam.width, cam.height / 2),
    axis: ray(cam.width / 2, cam.height / 2),
  };
}

export class CameraPanel {
  constructor(container, cameras) {
    this.views = cameras
      .filter((c) => c.projection)
      .map((cam) => {
        const canvas = document.createElement('canvas');
        canvas.dataset.camera = cam.id;
        canvas.width = 640;
        canvas.height = Math.round((640 * cam.height) / cam.width);
        container.append(canvas);
        return { cam, canvas, ctx: canvas.getContext('2d') };
      });
    if (!this.views.length) container.textContent = 'No calibrated camera.';
  }

  draw(state) {
    for (const { cam, canvas, ctx } of this.views) {
      const k = canvas.width / cam.width;
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = '#0b0e13';
      ctx.fillRect(0, 0, canvas.width, canvas.height);
      ctx.setTransform(k, 0, 0, k, 0, 0);
      ctx.lineWidth = 2 / k;
      ctx.font = `${14 / k}px system-ui`;
      const det = state.detections.get(cam.id);
      if (det) {
        const stale = state.t - det.t > 1;
        ctx.strokeStyle = stale ? 'rgba(200,200,200,0.3)' : 'rgba(235,235,235,0.9)';
        ctx.fillStyle = ctx.strokeStyle;
        for (const b of det.boxes) {
          ctx.strokeRect(b.x, b.y, b.w, b.h);
          if (b.score != null) ctx.fillText(b.score.toFixed(2), b.x, b.y - 4 / k);
        }
      }
      for (const tr of state.visibleTracks()) {
        const p = project(cam.projection, tr.position);
        if (!p) continue;
        const top = project(cam.projection, [tr.position[0], tr.position[1], tr.position[2] + 0.12]);
        const r = top ? Math.max(4 / k, Math.hypot(top[0] - p[0], top[1] - p[1])) : 8 / k;
        ctx.strokeStyle = labelColor(tr.label, tr.alpha);
        ctx.fillStyle = labelColor(tr.label, tr.alpha);
        ctx.beginPath();
        ctx.arc(p[0], p[1], r, 0, 2 * Math.PI);
        ctx.stroke();
        ctx.beginPath();
        ctx.arc(p[0], p[1], 3 / k, 0, 2 * Math.PI);
        ctx.fill();
        ctx.fillText(tr.label, p[0] + r + 4 / k, p[1]);
      }
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = '#8a94a3';
      ctx.font = '12px system-ui';
      ctx.fillText(`${cam.id}  ${cam.width}x${cam.height}`, 6, 14);
    }
  }
}
