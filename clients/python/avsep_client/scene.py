"""Reading what a client streams: WAV files, a scene folder's calibration (scene.json) as the
body that creates a session, and its ``detections.jsonl`` (docs/scene-format.md)."""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .client import Detections

# Fields of scene.json that describe the sensors; the others name files of the folder.
_SESSION_FIELDS = ("name", "sample_rate", "speed_of_sound", "arrays", "cameras", "region")
_PCM, _FLOAT, _EXTENSIBLE = 1, 3, 0xFFFE


def read_wav(path: str | Path) -> tuple[int, npt.NDArray[np.float32]]:
    """A PCM (16, 24 or 32-bit) or IEEE-float (32-bit) WAV file as (sample rate, samples shaped
    (frames, channels) as float32 in [-1, 1])."""
    data = Path(path).read_bytes()
    if data[:4] != b"RIFF" or data[8:12] != b"WAVE":
        raise ValueError(f"{path}: not a RIFF/WAVE file")
    fmt: tuple[int, int, int, int] | None = None
    pos = 12
    while pos + 8 <= len(data):
        cid, size = data[pos : pos + 4], struct.unpack_from("<I", data, pos + 4)[0]
        body = data[pos + 8 : pos + 8 + size]
        if cid == b"fmt ":
            tag, channels, rate = struct.unpack_from("<HHI", body)
            bits = struct.unpack_from("<H", body, 14)[0]
            if tag == _EXTENSIBLE and len(body) >= 26:
                tag = struct.unpack_from("<H", body, 24)[0]
            fmt = (tag, channels, rate, bits)
        elif cid == b"data":
            if fmt is None:
                raise ValueError(f"{path}: data chunk before the fmt chunk")
            return fmt[2], _samples(path, body, *fmt)
        pos += 8 + size + (size & 1)
    raise ValueError(f"{path}: no data chunk")


def _samples(
    path: str | Path, body: bytes, tag: int, channels: int, rate: int, bits: int
) -> npt.NDArray[np.float32]:
    if channels == 0:
        raise ValueError(f"{path}: no channels")
    width = bits // 8
    body = body[: len(body) // (width * channels) * width * channels]
    if tag == _FLOAT and bits == 32:
        x = np.frombuffer(body, dtype="<f4").astype(np.float32)
    elif tag == _PCM and bits in (16, 32):
        raw = np.frombuffer(body, dtype="<i2" if bits == 16 else "<i4")
        x = (raw.astype(np.float64) / float(1 << (bits - 1))).astype(np.float32)
    elif tag == _PCM and bits == 24:
        b = np.frombuffer(body, dtype=np.uint8).reshape(-1, 3).astype(np.int32)
        raw = (b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)) << 8 >> 8
        x = (raw.astype(np.float64) / float(1 << 23)).astype(np.float32)
    else:
        raise ValueError(f"{path}: format {tag} with {bits} bits is not supported")
    return x.reshape(-1, channels)


def session_body(scene_json: str | Path | dict[str, Any]) -> dict[str, Any]:
    """The body of ``POST /v1/sessions`` for the sensors of a scene.json (a path or its parsed
    content): sample rate, speed of sound, arrays, cameras and region."""
    d = (
        json.loads(Path(scene_json).read_text())
        if isinstance(scene_json, (str, Path))
        else scene_json
    )
    return {k: d[k] for k in _SESSION_FIELDS if k in d}


def read_detections(path: str | Path) -> list[Detections]:
    """The lines of a ``detections.jsonl`` file."""
    out = []
    for line in Path(path).read_text().splitlines():
        if line.strip():
            d = json.loads(line)
            out.append(Detections(t=float(d["t"]), camera=str(d["camera"]), boxes=d["boxes"]))
    return out


def write_wav(path: str | Path, rate: int, samples: npt.ArrayLike) -> None:
    """Writes float samples shaped (frames,) or (frames, channels) as a 32-bit float WAV."""
    x = np.asarray(samples, dtype="<f4")
    if x.ndim == 1:
        x = x[:, np.newaxis]
    channels = x.shape[1]
    body = x.tobytes()
    fmt = struct.pack("<HHIIHH", _FLOAT, channels, rate, rate * 4 * channels, 4 * channels, 32)
    head = b"RIFF" + struct.pack("<I", 4 + 8 + len(fmt) + 8 + len(body)) + b"WAVE"
    chunks = b"fmt " + struct.pack("<I", len(fmt)) + fmt + b"data" + struct.pack("<I", len(body))
    Path(path).write_bytes(head + chunks + body)
