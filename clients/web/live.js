// What the live view knows of a session, updated per message and read per animation frame:
// the tracks with their trails, the latest camera detections, and counters for tests.

const TRAIL_POINTS = 80; // about 10 s at the default 128 ms step
const FORGET_S = 3; // an ended track fades out over this long

export class LiveState {
  constructor(info) {
    this.info = info;
    this.tracks = new Map(); // label -> {label, position, velocity, speaking, existence, t, live, trail}
    this.step = -1;
    this.t = 0;
    this.steps = 0;
    this.detections = new Map(); // camera id -> {t, boxes}
    this.dirty = true;
  }

  applyTracks(msg) {
    const seen = new Set();
    for (const tr of msg.tracks) {
      let s = this.tracks.get(tr.label);
      if (!s) {
        s = { label: tr.label, trail: [] };
        this.tracks.set(tr.label, s);
      }
      Object.assign(s, {
        position: tr.position,
        velocity: tr.velocity,
        speaking: tr.speaking ?? 0,
        existence: tr.existence ?? 1,
        t: msg.t,
        live: true,
      });
      s.trail.push([tr.position[0], tr.position[1]]);
      if (s.trail.length > TRAIL_POINTS) s.trail.shift();
      seen.add(tr.label);
    }
    for (const [label, s] of this.tracks) {
      if (seen.has(label)) continue;
      s.live = false;
      if (msg.t - s.t > FORGET_S || msg.t < s.t) this.tracks.delete(label);
    }
    this.step = msg.step;
    this.t = msg.t;
    this.steps += 1;
    this.dirty = true;
  }

  applyDetections(list) {
    this.detections = new Map(list.cameras.map((c) => [c.camera, c]));
    this.dirty = true;
  }

  /** Tracks to draw, with an opacity that fades ended ones. */
  visibleTracks() {
    const out = [];
    for (const s of this.tracks.values()) {
      const alpha = s.live ? Math.max(0.35, s.existence) : Math.max(0, 1 - (this.t - s.t) / FORGET_S) * 0.4;
      if (alpha > 0) out.push({ ...s, alpha });
    }
    return out;
  }
}
