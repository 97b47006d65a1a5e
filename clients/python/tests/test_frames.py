"""The binary layout of api/protocol.md, byte for byte."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from avsep_client import FrameError, SampleFormat, decode_separated, encode_audio, to_i16


def test_audio_frames_follow_the_documented_header() -> None:
    x = np.array([[0.5, -0.25], [0.0, 1.0], [-1.0, 0.125]], dtype=np.float32)
    f = encode_audio(x, 48_000)
    assert f[:4] == b"AVSA" and f[4] == 1 and f[5] == 2
    assert struct.unpack_from("<HQII", f, 6) == (2, 48_000, 3, 0)
    assert np.array_equal(np.frombuffer(f[24:], "<f4").reshape(3, 2), x)
    g = encode_audio(x, 7, "i16")
    assert g[5] == 1 and len(g) == 24 + 3 * 2 * 2
    assert np.frombuffer(g[24:], "<i2").tolist() == [16384, -8192, 0, 32767, -32768, 4096]


def test_i16_rounds_half_away_from_zero_like_the_server() -> None:
    assert to_i16([0.5 / 32768, -0.5 / 32768, 1.5 / 32768, 2.0, np.nan]).tolist() == [
        1, -1, 2, 32767, 0,
    ]


def test_separated_audio_decodes_label_and_sample_index() -> None:
    samples = np.array([0.1, -0.2, 0.3], dtype="<f4")
    head = struct.pack("<4sBBHQIIQ", b"AVSO", 1, 2, 0, 12, 1, 3, 1024)
    a = decode_separated(head + samples.tobytes())
    assert (a.label, a.first_sample, a.end, a.format) == ("12.1", 1024, 1027, SampleFormat.F32)
    assert np.array_equal(a.samples, samples)
    ints = struct.pack("<4sBBHQIIQ", b"AVSO", 1, 1, 0, 3, 0, 2, 0) + struct.pack("<hh", 16384, -32768)
    assert decode_separated(ints).samples.tolist() == [0.5, -1.0]
    with pytest.raises(FrameError) as e:
        decode_separated(head + samples.tobytes()[:-1])
    assert e.value.field == "samples"
    with pytest.raises(FrameError) as e:
        decode_separated(b"XVSO" + head[4:])
    assert e.value.field == "magic"
