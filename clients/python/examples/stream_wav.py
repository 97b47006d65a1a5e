"""Streams a WAV file (and optionally a camera's detections) to an avsep server and prints the
tracks as they arrive; optionally saves each label's separated voice.

    avsep serve --no-zenoh &
    avsep simulate --preset uca8 --seed 3 --out /tmp/uca8
    python examples/stream_wav.py --calibration /tmp/uca8/scene.json --wav /tmp/uca8/audio.wav \
        --detections /tmp/uca8/detections.jsonl --save-audio /tmp/uca8-voices
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt

from avsep_client import (
    Client,
    Closed,
    ErrorMessage,
    Event,
    SeparatedAudio,
    Tracks,
    read_detections,
    read_wav,
    session_body,
    write_wav,
)


async def run(args: argparse.Namespace) -> int:
    client = Client(args.url, admin_key=args.admin_key)
    settings = json.loads(args.settings) if args.settings else None
    session = client.create_session(session_body(args.calibration), settings)
    rate, audio = read_wav(args.wav)
    detections = read_detections(args.detections) if args.detections else []
    print(f"session {session.id}: streaming {audio.shape[0] / rate:.2f} s of {audio.shape[1]}-channel audio")
    voices: dict[str, npt.NDArray[np.float32]] = {}
    status = 0
    async with session.stream(audio_format=args.format) as stream:
        async for msg in stream.feed(
            audio, detections, block=args.block, fmt=args.format, realtime=args.realtime
        ):
            if isinstance(msg, Tracks):
                people = "; ".join(
                    f"{t.label} at ({t.position[0]:.2f}, {t.position[1]:.2f}, {t.position[2]:.2f}) m"
                    f" speaking {t.speaking:.2f}"
                    for t in msg.tracks
                )
                print(f"step {msg.step} t={msg.t:.3f} s: {people}")
            elif isinstance(msg, Event):
                print(f"event {msg.event} {msg.label or msg.code or ''}")
            elif isinstance(msg, ErrorMessage):
                print(f"refused: {msg.code} (field {msg.field}): {msg.message}", file=sys.stderr)
            elif isinstance(msg, SeparatedAudio):
                buf = voices.setdefault(msg.label, np.zeros(audio.shape[0], dtype=np.float32))
                n = max(0, min(len(msg.samples), len(buf) - msg.first_sample))
                buf[msg.first_sample : msg.first_sample + n] = msg.samples[:n]
            elif isinstance(msg, Closed):
                print(f"closed: {msg.code} {msg.reason}")
                status = 0 if msg.code == 1000 else 1
    if args.save_audio:
        out = Path(args.save_audio)
        out.mkdir(parents=True, exist_ok=True)
        for label, samples in voices.items():
            write_wav(out / f"{label}.wav", rate, samples)
        print(f"wrote {len(voices)} voices to {out}")
    return status


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--url", default="http://127.0.0.1:8080", help="server address")
    p.add_argument("--calibration", required=True, help="scene.json whose sensors the session gets")
    p.add_argument("--wav", required=True, help="multichannel WAV at the session's sample rate")
    p.add_argument("--detections", help="detections.jsonl of the cameras")
    p.add_argument("--settings", help='pipeline settings as JSON, e.g. \'{"seed": 5}\'')
    p.add_argument("--admin-key", help="admin key, when the server has one")
    p.add_argument("--format", choices=["f32", "i16"], default="f32", help="sample encoding")
    p.add_argument("--block", type=int, default=1024, help="samples per channel per frame")
    p.add_argument("--realtime", action="store_true", help="pace the audio in real time")
    p.add_argument("--save-audio", help="folder to write <label>.wav into")
    return asyncio.run(run(p.parse_args()))


if __name__ == "__main__":
    sys.exit(main())
