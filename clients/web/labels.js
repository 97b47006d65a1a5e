// Stable colours for track labels ("k.i"): the same label always gets the same hue, and
// consecutive labels land far apart on the colour wheel (golden angle).

const cache = new Map();

function hue(label) {
  const [k, i] = label.split('.').map(Number);
  const n = (Number.isFinite(k) ? k : 0) * 7 + (Number.isFinite(i) ? i : 0) * 3;
  return (n * 137.508) % 360;
}

export function labelColor(label, alpha = 1) {
  const key = `${label}|${alpha}`;
  let c = cache.get(key);
  if (!c) {
    c = `hsla(${hue(label).toFixed(1)}, 80%, 62%, ${alpha})`;
    cache.set(key, c);
  }
  return c;
}
