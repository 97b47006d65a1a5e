"""JSON messages the server sends on a stream (api/protocol.md, "Server to client"), as typed
dataclasses. Units follow the scene format: seconds, metres, degrees."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Union

from .frames import SeparatedAudio

Vec3 = tuple[float, float, float]


def _vec3(v: Any) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


@dataclass(frozen=True)
class Welcome:
    """The first message of a stream: what the session expects."""

    session: str
    protocol: int
    sample_rate: int
    channels: int
    arrays: list[str]
    cameras: list[str]
    next_sample: int
    next_step: int
    step_s: float
    audio_delay_samples: int
    queue_depth: int
    max_audio_samples: int
    max_message_bytes: int
    max_measurements: int


@dataclass(frozen=True)
class Track:
    """One track of a step: a person, under a label ``"k.i"`` that never changes while they
    are tracked and is never reused."""

    label: str
    position: Vec3
    """Position (m)."""
    velocity: Vec3
    """Velocity (m/s)."""
    existence: float
    """Existence probability."""
    speaking: float
    """Probability that the person is speaking now."""
    covariance: list[list[float]] | None = None
    """Position covariance (m^2), row by row, when the server sends it."""


@dataclass(frozen=True)
class Tracks:
    """The tracker's estimate after one step."""

    step: int
    t: float
    """Time the estimate refers to (s, session time)."""
    tracks: list[Track]


@dataclass(frozen=True)
class Measurements:
    """The localiser's output for one array and step (the fields of a measurements line)."""

    t: float
    array: str
    doas: list[dict[str, float]]
    points: list[Vec3]
    activity: float | None


@dataclass(frozen=True)
class Event:
    """``track_born``, ``track_ended`` (with ``t`` and ``label``) or ``warning`` (with
    ``code`` and ``message``)."""

    event: str
    t: float | None = None
    label: str | None = None
    code: str | None = None
    message: str | None = None


@dataclass(frozen=True)
class ErrorMessage:
    """A refused message: the session goes on, and nothing accepted before is lost."""

    code: str
    message: str
    field: str | None = None


@dataclass(frozen=True)
class Closed:
    """The stream's end: the WebSocket close code and reason (1000 after ``finish``)."""

    code: int
    reason: str


@dataclass(frozen=True)
class Unknown:
    """A message this client does not know (a newer server); kept as parsed JSON."""

    data: dict[str, Any] = field(default_factory=dict)


Message = Union[
    Welcome, Tracks, Measurements, Event, ErrorMessage, SeparatedAudio, Closed, Unknown
]
"""Everything a stream yields."""


def parse_message(text: str | bytes) -> Message:
    """Parses one JSON text message of the server."""
    d = json.loads(text)
    kind = d.get("type")
    if kind == "tracks":
        return Tracks(
            step=int(d["step"]),
            t=float(d["t"]),
            tracks=[
                Track(
                    label=str(x["label"]),
                    position=_vec3(x["position"]),
                    velocity=_vec3(x.get("velocity", (0.0, 0.0, 0.0))),
                    existence=float(x.get("existence", 1.0)),
                    speaking=float(x.get("speaking", 0.0)),
                    covariance=x.get("covariance"),
                )
                for x in d["tracks"]
            ],
        )
    if kind == "event":
        return Event(
            event=str(d["event"]),
            t=d.get("t"),
            label=d.get("label"),
            code=d.get("code"),
            message=d.get("message"),
        )
    if kind == "error":
        e = d["error"]
        return ErrorMessage(code=str(e["code"]), message=str(e["message"]), field=e.get("field"))
    if kind == "measurements":
        return Measurements(
            t=float(d["t"]),
            array=str(d["array"]),
            doas=list(d.get("doas", [])),
            points=[_vec3(p) for p in d.get("points", [])],
            activity=d.get("activity"),
        )
    if kind == "welcome":
        return Welcome(
            session=str(d["session"]),
            protocol=int(d["protocol"]),
            sample_rate=int(d["sample_rate"]),
            channels=int(d["channels"]),
            arrays=list(d["arrays"]),
            cameras=list(d["cameras"]),
            next_sample=int(d["next_sample"]),
            next_step=int(d.get("next_step", 0)),
            step_s=float(d["step_s"]),
            audio_delay_samples=int(d.get("audio_delay_samples", 0)),
            queue_depth=int(d.get("queue_depth", 0)),
            max_audio_samples=int(d.get("max_audio_samples", 0)),
            max_message_bytes=int(d.get("max_message_bytes", 0)),
            max_measurements=int(d.get("max_measurements", 0)),
        )
    return Unknown(d)
