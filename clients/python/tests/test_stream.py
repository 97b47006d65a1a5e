"""The client against a real server: a simulated scene streamed over WebSocket gives the tracks
and the separated audio of `avsep process` on the same scene (labels "k.i", each label's audio
at the right sample indices), and malformed frames sent in the middle come back as errors naming
the problem while the session goes on."""

from __future__ import annotations

import asyncio
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt

from avsep_client import (
    ApiError,
    Client,
    Closed,
    Detections,
    ErrorMessage,
    Event,
    Message,
    SampleFormat,
    SeparatedAudio,
    Session,
    Tracks,
    encode_audio,
    read_detections,
    read_wav,
    session_body,
)

BLOCK = 1024


async def stream_with_bad_frames(
    session: Session, audio: npt.NDArray[np.float32], dets: list[Detections], split: int
) -> list[Message]:
    rate = session.info["sample_rate"]
    got: list[Message] = []
    async with session.stream() as s:
        first = [d for d in dets if d.t < split / rate]
        async for m in s.feed(audio[:split], first, block=BLOCK, finish=False):
            got.append(m)
        good = encode_audio(audio[split : split + BLOCK], split)
        await s.send_raw(good[:-3])
        await s.send_raw(encode_audio(audio[split : split + BLOCK, :3], split))
        await s.send_raw(b"AVSX" + good[4:])
        rest = [d for d in dets if d.t >= split / rate]
        async for m in s.feed(audio[split:], rest, block=BLOCK):
            got.append(m)
    return got


def offline_tracks(out: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (out / "tracks.jsonl").read_text().splitlines() if line]


def test_stream_gives_the_offline_tracks_and_audio_and_names_bad_frames(
    server: str, scene: Path, offline: Path, settings: dict[str, int]
) -> None:
    client = Client(server)
    session = client.create_session(session_body(scene / "scene.json"), settings)
    rate, audio = read_wav(scene / "audio.wav")
    assert rate == session.info["sample_rate"] and audio.shape[1] == session.info["channels"]
    dets = read_detections(scene / "detections.jsonl")
    assert dets, "the scene has a camera"
    split = 16 * BLOCK
    got = asyncio.run(stream_with_bad_frames(session, audio, dets, split))

    # Each malformed frame is refused by name; the session went on (every step arrived).
    errors = [(m.code, m.field) for m in got if isinstance(m, ErrorMessage)]
    assert errors == [("truncated", "samples"), ("bad_channels", "channels"), ("bad_magic", "magic")]
    assert isinstance(got[-1], Closed) and got[-1].code == 1000, got[-1]

    steps = [m for m in got if isinstance(m, Tracks)]
    expected = offline_tracks(offline)
    assert [s.step for s in steps] == list(range(len(expected)))
    labels: set[str] = set()
    for s, e in zip(steps, expected):
        assert abs(s.t - float(e["t"])) < 1e-12  # type: ignore[arg-type]
        want = e["tracks"]
        assert isinstance(want, list)
        assert [t.label for t in s.tracks] == [w["label"] for w in want]
        for t, w in zip(s.tracks, want):
            assert re.fullmatch(r"\d+\.\d+", t.label)
            assert np.allclose(t.position, w["position"], rtol=0, atol=1e-9)
            labels.add(t.label)
    assert labels, "no tracks at all"
    born = {m.label for m in got if isinstance(m, Event) and m.event == "track_born"}
    assert born == labels

    # Separated audio: chunks of each label in sample order, never overlapping, on the input's
    # sample axis; put together they are the offline run's audio/<label>.wav.
    chunks: dict[str, list[SeparatedAudio]] = {}
    for m in got:
        if isinstance(m, SeparatedAudio):
            chunks.setdefault(m.label, []).append(m)
    assert set(chunks) == {p.stem for p in (offline / "audio").glob("*.wav")}
    frames = audio.shape[0]
    for label, cs in chunks.items():
        assert all(c.format is SampleFormat.F32 for c in cs)
        assert all(b.first_sample >= a.end for a, b in zip(cs, cs[1:])), label
        assert 0 <= cs[0].first_sample < frames
        live = np.zeros(frames, dtype=np.float32)
        for c in cs:
            n = max(0, min(len(c.samples), frames - c.first_sample))
            live[c.first_sample : c.first_sample + n] = c.samples[:n]
        _, want_audio = read_wav(offline / "audio" / f"{label}.wav")
        assert np.array_equal(live, want_audio[:, 0]), label


async def stream_i16(session: Session, audio: npt.NDArray[np.float32]) -> list[Message]:
    async with session.stream(audio_format="i16") as s:
        return [m async for m in s.feed(audio, fmt=SampleFormat.I16, block=BLOCK)]


def test_i16_frames_and_i16_audio_out(server: str, scene: Path, settings: dict[str, int]) -> None:
    client = Client(server)
    session = client.create_session(session_body(scene / "scene.json"), settings)
    rate, audio = read_wav(scene / "audio.wav")
    got = asyncio.run(stream_i16(session, audio[: rate]))
    assert not [m for m in got if isinstance(m, ErrorMessage)]
    steps = [m.step for m in got if isinstance(m, Tracks)]
    assert steps == list(range(len(steps))) and len(steps) >= rate // 2048
    out = [m for m in got if isinstance(m, SeparatedAudio)]
    assert out and all(m.format is SampleFormat.I16 for m in out)
    assert isinstance(got[-1], Closed) and got[-1].code == 1000


def test_a_bad_session_body_names_the_field(server: str, scene: Path) -> None:
    body = session_body(scene / "scene.json")
    body["arrays"][0]["mics"][0] = [0.0, 0.0]
    try:
        Client(server).create_session(body)
    except ApiError as e:
        assert e.status == 422 and e.field == "arrays[0].mics[0]", e
    else:
        raise AssertionError("the server accepted a 2-D microphone")


def test_the_example_streams_a_wav_file_and_saves_each_voice(
    server: str, scene: Path, offline: Path, tmp_path: Path
) -> None:
    example = Path(__file__).resolve().parents[1] / "examples" / "stream_wav.py"
    r = subprocess.run(
        [sys.executable, example, "--url", server, "--calibration", scene / "scene.json",
         "--wav", scene / "audio.wav", "--detections", scene / "detections.jsonl",
         "--settings", json.dumps({"seed": 5}), "--save-audio", tmp_path / "voices"],
        capture_output=True, text=True, timeout=120,
        env={**os.environ, "PYTHONPATH": str(example.parents[1])},
    )
    assert r.returncode == 0, r.stderr
    steps = [line for line in r.stdout.splitlines() if line.startswith("step ")]
    assert len(steps) == len(offline_tracks(offline))
    voices = {p.stem for p in (tmp_path / "voices").glob("*.wav")}
    assert voices == {p.stem for p in (offline / "audio").glob("*.wav")}
    for label in voices:
        _, got = read_wav(tmp_path / "voices" / f"{label}.wav")
        _, want = read_wav(offline / "audio" / f"{label}.wav")
        assert np.array_equal(got, want), label
