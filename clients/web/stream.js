// The session's WebSocket stream: JSON messages (welcome, tracks, events, errors) and binary
// separated-audio frames ("AVSO" header, api/protocol.md).

const AUDIO_OUT_HEADER = 32;

/** Decodes one separated-audio frame; null when it is not one. */
export function decodeAudioFrame(buf) {
  if (buf.byteLength < AUDIO_OUT_HEADER) return null;
  const dv = new DataView(buf);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic !== 'AVSO' || dv.getUint8(4) !== 1) return null;
  const format = dv.getUint8(5);
  const birth = Number(dv.getBigUint64(8, true));
  const index = dv.getUint32(16, true);
  const frames = dv.getUint32(20, true);
  const firstSample = Number(dv.getBigUint64(24, true));
  let samples;
  if (format === 1 && buf.byteLength === AUDIO_OUT_HEADER + 2 * frames) {
    const raw = new Int16Array(buf, AUDIO_OUT_HEADER, frames);
    samples = new Float32Array(frames);
    for (let i = 0; i < frames; i++) samples[i] = raw[i] / 32768;
  } else if (format === 2 && buf.byteLength === AUDIO_OUT_HEADER + 4 * frames) {
    samples = new Float32Array(buf.slice(AUDIO_OUT_HEADER));
  } else {
    return null;
  }
  return { label: `${birth}.${index}`, firstSample, samples };
}

/**
 * Opens the stream at `url` asking for tracks, events and 16-bit audio of every label;
 * calls `on.message(json)`, `on.audio(frame)`, `on.close(event)`.
 */
export function openStream(url, on) {
  const ws = new WebSocket(url);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    const hello = {
      type: 'hello',
      client: 'dashboard',
      outputs: { tracks: true, events: true, measurements: false, audio: { format: 'i16' } },
    };
    ws.send(JSON.stringify(hello));
  };
  ws.onmessage = (e) => {
    if (typeof e.data === 'string') {
      let msg;
      try {
        msg = JSON.parse(e.data);
      } catch {
        return;
      }
      on.message?.(msg);
    } else {
      const frame = decodeAudioFrame(e.data);
      if (frame) on.audio?.(frame);
    }
  };
  ws.onclose = (e) => on.close?.(e);
  return ws;
}
