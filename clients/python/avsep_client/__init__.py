"""A client of avsep's live sessions: create a session over REST, stream multichannel audio and
camera detections over WebSocket, and receive tracks, events and each label's separated audio.

    from avsep_client import Client, read_wav, session_body

    client = Client("http://127.0.0.1:8080")
    session = client.create_session(session_body("scene/scene.json"))
    rate, audio = read_wav("scene/audio.wav")
    async with session.stream() as stream:
        async for msg in stream.feed(audio):
            ...

The wire format is api/protocol.md of the avsep repository.
"""

from .client import ApiError, Client, Detections, Session, Stream
from .frames import (
    FrameError,
    SampleFormat,
    SeparatedAudio,
    decode_separated,
    encode_audio,
    to_i16,
)
from .messages import (
    Closed,
    ErrorMessage,
    Event,
    Measurements,
    Message,
    Track,
    Tracks,
    Unknown,
    Welcome,
    parse_message,
)
from .scene import read_detections, read_wav, session_body, write_wav

__all__ = [
    "ApiError",
    "Client",
    "Closed",
    "Detections",
    "ErrorMessage",
    "Event",
    "FrameError",
    "Measurements",
    "Message",
    "SampleFormat",
    "SeparatedAudio",
    "Session",
    "Stream",
    "Track",
    "Tracks",
    "Unknown",
    "Welcome",
    "decode_separated",
    "encode_audio",
    "parse_message",
    "read_detections",
    "read_wav",
    "session_body",
    "to_i16",
    "write_wav",
]
__version__ = "0.1.0"
