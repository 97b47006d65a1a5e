"""Binary audio frames of the stream protocol (api/protocol.md), little-endian.

Client to server, multichannel audio (``AVSA``, 24-byte header)::

    magic "AVSA" | version u8 = 1 | format u8 (1 = i16, 2 = f32) | channels u16
    | first sample u64 | frame count u32 | reserved u32 = 0 | interleaved samples

Server to client, one label's separated audio (``AVSO``, 32-byte header)::

    magic "AVSO" | version u8 = 1 | format u8 | reserved u16 | label birth step u64
    | label index u32 | frame count u32 | first sample u64 | mono samples
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

AUDIO_IN_MAGIC = b"AVSA"
AUDIO_OUT_MAGIC = b"AVSO"
FRAME_VERSION = 1
_IN_HEADER = struct.Struct("<4sBBHQII")
_OUT_HEADER = struct.Struct("<4sBBHQIIQ")
AUDIO_IN_HEADER = _IN_HEADER.size
AUDIO_OUT_HEADER = _OUT_HEADER.size


class SampleFormat(enum.IntEnum):
    """Sample encoding of a binary frame (the code in its header)."""

    I16 = 1
    """Signed 16-bit PCM, full scale 32768."""
    F32 = 2
    """IEEE 754 32-bit float in [-1, 1]."""

    @property
    def dtype(self) -> np.dtype[np.int16] | np.dtype[np.float32]:
        """The little-endian numpy type of one sample."""
        return np.dtype("<i2") if self is SampleFormat.I16 else np.dtype("<f4")

    @classmethod
    def parse(cls, name: str | SampleFormat) -> SampleFormat:
        """``"i16"`` or ``"f32"`` (the names the JSON messages use)."""
        if isinstance(name, SampleFormat):
            return name
        try:
            return {"i16": cls.I16, "f32": cls.F32}[name]
        except KeyError:
            raise ValueError(f"{name!r} is not a sample format (i16, f32)") from None

    @property
    def json_name(self) -> str:
        """The name in JSON messages (``hello``'s ``audio.format``)."""
        return "i16" if self is SampleFormat.I16 else "f32"


class FrameError(ValueError):
    """A frame that does not follow the layout; ``field`` names the part at fault."""

    def __init__(self, code: str, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.code = code
        self.field = field


def to_i16(samples: npt.ArrayLike) -> npt.NDArray[np.int16]:
    """Float samples in [-1, 1] to i16 as the server's own encoder does it: x * 32768 rounded
    half away from zero, clipped to [-32768, 32767]; non-finite samples become 0."""
    x = np.asarray(samples, dtype=np.float64) * 32768.0
    x = np.where(np.isfinite(x), x, 0.0)
    rounded = np.sign(x) * np.floor(np.abs(x) + 0.5)
    out: npt.NDArray[np.int16] = np.clip(rounded, -32768, 32767).astype(np.int16)
    return out


def encode_audio(
    samples: npt.ArrayLike,
    first_sample: int,
    fmt: SampleFormat | str = SampleFormat.F32,
) -> bytes:
    """One ``AVSA`` frame: ``samples`` shaped (frames, channels) (or 1-D for one channel), float
    in [-1, 1], or int16 when ``fmt`` is i16, starting at sample index ``first_sample``."""
    fmt = SampleFormat.parse(fmt)
    a = np.asarray(samples)
    if a.ndim == 1:
        a = a[:, np.newaxis]
    if a.ndim != 2 or a.shape[1] == 0:
        raise ValueError(f"audio must be shaped (frames, channels), not {a.shape}")
    if first_sample < 0:
        raise ValueError(f"first_sample must be >= 0, not {first_sample}")
    frames, channels = a.shape
    if fmt is SampleFormat.I16:
        body = (a if a.dtype == np.int16 else to_i16(a)).astype("<i2").tobytes()
    else:
        body = a.astype("<f4").tobytes()
    head = _IN_HEADER.pack(
        AUDIO_IN_MAGIC, FRAME_VERSION, int(fmt), channels, first_sample, frames, 0
    )
    return head + body


@dataclass(frozen=True)
class SeparatedAudio:
    """A chunk of one label's separated voice, on the input's sample axis."""

    label: str
    """The track label ``"k.i"``."""
    first_sample: int
    """Index of the chunk's first sample (the input's sample index)."""
    samples: npt.NDArray[np.float32]
    """Mono samples as float32 in [-1, 1] (i16 frames are scaled by 1/32768)."""
    format: SampleFormat
    """The encoding the chunk arrived in."""

    @property
    def end(self) -> int:
        """One past the chunk's last sample index."""
        return self.first_sample + len(self.samples)


def decode_separated(data: bytes) -> SeparatedAudio:
    """Decodes an ``AVSO`` frame; raises :class:`FrameError` naming the bad part."""
    if len(data) < AUDIO_OUT_HEADER:
        raise FrameError("truncated", "header", f"{len(data)} bytes is shorter than the header")
    magic, version, code, _, birth, index, frames, first = _OUT_HEADER.unpack_from(data)
    if magic != AUDIO_OUT_MAGIC:
        raise FrameError("bad_magic", "magic", 'a separated-audio frame starts with "AVSO"')
    if version != FRAME_VERSION:
        raise FrameError("bad_version", "version", f"version {version} is not supported")
    try:
        fmt = SampleFormat(code)
    except ValueError:
        raise FrameError("bad_format", "sample_format", f"unknown code {code}") from None
    payload = data[AUDIO_OUT_HEADER:]
    if len(payload) != frames * fmt.dtype.itemsize:
        raise FrameError(
            "truncated", "samples", "payload length does not match the frame count"
        )
    raw = np.frombuffer(payload, dtype=fmt.dtype)
    samples = (raw.astype(np.float32) / np.float32(32768.0)) if fmt is SampleFormat.I16 else raw
    return SeparatedAudio(
        label=f"{birth}.{index}",
        first_sample=first,
        samples=samples.astype(np.float32, copy=False),
        format=fmt,
    )
