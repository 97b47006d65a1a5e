"""Sessions over REST (stdlib urllib) and their live streams over WebSocket (websockets)."""

from __future__ import annotations

import asyncio
import json
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import AsyncIterator, Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from .frames import FrameError, SampleFormat, decode_separated, encode_audio
from .messages import Closed, ErrorMessage, Message, Tracks, Welcome, parse_message


class ApiError(Exception):
    """A REST call the server refused: HTTP status, and the error body's code and field."""

    def __init__(self, status: int, code: str, message: str, field: str | None) -> None:
        where = f" (field {field})" if field else ""
        super().__init__(f"HTTP {status} {code}{where}: {message}")
        self.status = status
        self.code = code
        self.message = message
        self.field = field


class Client:
    """A server's REST API under ``/v1``. ``admin_key`` is needed when the server has one."""

    def __init__(self, url: str, admin_key: str | None = None, timeout_s: float = 30.0) -> None:
        self.url = url.rstrip("/")
        self.admin_key = admin_key
        self.timeout_s = timeout_s

    def request(
        self,
        method: str,
        path: str,
        body: Mapping[str, Any] | None = None,
        token: str | None = None,
    ) -> Any:
        """One JSON request; returns the parsed answer (``None`` when empty) or raises
        :class:`ApiError`."""
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.url + path, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        bearer = token or self.admin_key
        if bearer:
            req.add_header("Authorization", f"Bearer {bearer}")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as r:
                text = r.read()
        except urllib.error.HTTPError as e:
            raw = e.read()
            try:
                err = json.loads(raw)["error"]
                raise ApiError(e.code, err["code"], err["message"], err.get("field")) from None
            except (ValueError, KeyError, TypeError):
                raise ApiError(e.code, "http", raw.decode(errors="replace"), None) from None
        return json.loads(text) if text else None

    def health(self) -> dict[str, Any]:
        """``GET /healthz``."""
        out: dict[str, Any] = self.request("GET", "/healthz")
        return out

    def create_session(
        self, body: Mapping[str, Any], settings: Mapping[str, Any] | None = None
    ) -> Session:
        """``POST /v1/sessions`` with the room's sensors (``sample_rate``, ``arrays``,
        ``cameras``, ...; see :func:`avsep_client.scene.session_body`) and pipeline
        ``settings`` (``avsep config --defaults`` keys; absent ones keep their defaults)."""
        full = dict(body)
        if settings is not None:
            full["settings"] = dict(settings)
        r = self.request("POST", "/v1/sessions", full)
        return Session(
            client=self, id=r["id"], token=r["token"], stream_path=r["stream"], info=r["session"]
        )

    def session_info(self, session_id: str, token: str | None = None) -> dict[str, Any]:
        """``GET /v1/sessions/{id}`` (the session's token or the admin key)."""
        out: dict[str, Any] = self.request(
            "GET", f"/v1/sessions/{urllib.parse.quote(session_id)}", token=token
        )
        return out

    def delete_session(self, session_id: str) -> None:
        """``DELETE /v1/sessions/{id}`` (the admin key, when the server has one)."""
        self.request("DELETE", f"/v1/sessions/{urllib.parse.quote(session_id)}")


@dataclass
class Session:
    """A session created on a server: its id, the token that opens only it, and its info."""

    client: Client
    id: str
    token: str
    stream_path: str
    info: dict[str, Any]

    @property
    def stream_url(self) -> str:
        """The WebSocket address of the session's stream."""
        u = urllib.parse.urlsplit(self.client.url)
        scheme = "wss" if u.scheme == "https" else "ws"
        return f"{scheme}://{u.netloc}{self.stream_path}"

    def stream(
        self,
        audio_format: SampleFormat | str | None = SampleFormat.F32,
        labels: Sequence[str] | None = None,
        measurements: bool = False,
        client_name: str = "avsep-python",
    ) -> Stream:
        """The session's stream (``async with session.stream() as s``), asking for tracks,
        events and separated audio in ``audio_format`` (``None``: no audio), of every label or
        only ``labels``."""
        outputs: dict[str, Any] = {"tracks": True, "events": True, "measurements": measurements}
        if audio_format is not None:
            fmt = SampleFormat.parse(audio_format)
            outputs["audio"] = {
                "format": fmt.json_name,
                "labels": None if labels is None else list(labels),
            }
        return Stream(self.stream_url, self.token, {"client": client_name, "outputs": outputs})


@dataclass(frozen=True)
class Detections:
    """One camera frame's face boxes (the fields of a ``detections.jsonl`` line)."""

    t: float
    camera: str
    boxes: list[dict[str, Any]]
    """``{"x", "y", "w", "h"}`` in pixels, optional ``score`` and ``point`` ``[u, v]``."""

    def message(self) -> str:
        """The JSON message."""
        return json.dumps(
            {"type": "detections", "t": self.t, "camera": self.camera, "boxes": self.boxes}
        )


class Stream:
    """A session's live stream. Iterate it for what the server sends: :class:`Tracks`,
    :class:`~avsep_client.messages.Event`, :class:`ErrorMessage`,
    :class:`~avsep_client.frames.SeparatedAudio`, and finally :class:`Closed`."""

    def __init__(self, url: str, token: str, hello: Mapping[str, Any]) -> None:
        self._url = url
        self._token = token
        self._hello = dict(hello)
        self._ws: ClientConnection | None = None
        self.welcome: Welcome | None = None
        self.next_sample = 0
        """Where the audio continues (advanced by :meth:`send_audio`)."""
        self.steps_done = 0
        """Steps the session has reported."""
        self._progress = asyncio.Event()
        self._closed: Closed | None = None

    async def __aenter__(self) -> Stream:
        ws = await connect(
            self._url,
            additional_headers={"Authorization": f"Bearer {self._token}"},
            max_size=None,
        )
        first = parse_message(await ws.recv())
        if not isinstance(first, Welcome):
            await ws.close()
            raise ConnectionError(f"the first message was {first!r}, not a welcome")
        self._ws = ws
        self.welcome = first
        self.next_sample = first.next_sample
        self.steps_done = first.next_step
        await ws.send(json.dumps({"type": "hello", **self._hello}))
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._ws is not None:
            await self._ws.close()

    @property
    def ws(self) -> ClientConnection:
        """The open connection."""
        if self._ws is None:
            raise RuntimeError("the stream is not open (use `async with`)")
        return self._ws

    async def send_audio(
        self,
        samples: npt.ArrayLike,
        first_sample: int | None = None,
        fmt: SampleFormat | str = SampleFormat.F32,
    ) -> None:
        """Sends audio shaped (frames, channels), continuing at ``next_sample`` unless
        ``first_sample`` says where it starts."""
        a = np.asarray(samples)
        start = self.next_sample if first_sample is None else first_sample
        await self.ws.send(encode_audio(a, start, fmt))
        self.next_sample = max(self.next_sample, start + (a.shape[0] if a.ndim else 0))

    async def send_detections(self, d: Detections) -> None:
        """Sends one camera frame's detections."""
        await self.ws.send(d.message())

    async def send_raw(self, message: bytes | str) -> None:
        """Sends a message as it is (binary for bytes, text for str)."""
        await self.ws.send(message)

    async def finish(self) -> None:
        """Ends the input: the session processes what it holds, flushes the separated audio and
        closes the stream."""
        await self.ws.send(json.dumps({"type": "finish"}))

    def __aiter__(self) -> AsyncIterator[Message]:
        return self._messages()

    async def _messages(self) -> AsyncIterator[Message]:
        while (msg := await self.next_message()) is not None:
            yield msg

    async def next_message(self) -> Message | None:
        """The next message; :class:`Closed` when the stream closes, then ``None``. Safe to
        cancel while it waits (nothing is lost)."""
        if self._closed is not None:
            return None
        try:
            raw = await self.ws.recv()
        except ConnectionClosed as e:
            rcvd = e.rcvd
            self._closed = Closed(
                code=rcvd.code if rcvd else 1006, reason=rcvd.reason if rcvd else ""
            )
            self._progress.set()
            return self._closed
        msg: Message
        if isinstance(raw, bytes):
            try:
                msg = decode_separated(raw)
            except FrameError as e:
                msg = ErrorMessage(code="client_parse", message=str(e), field=e.field)
        else:
            msg = parse_message(raw)
        if isinstance(msg, Tracks):
            self.steps_done = max(self.steps_done, msg.step + 1)
            self._progress.set()
        return msg

    async def _wait_for_steps(self, audio_end: int, lead: int, step_samples: int) -> None:
        while audio_end > self.steps_done * step_samples + lead and self._closed is None:
            self._progress.clear()
            await self._progress.wait()

    async def feed(
        self,
        audio: npt.ArrayLike,
        detections: Iterable[Detections] = (),
        block: int = 1024,
        fmt: SampleFormat | str = SampleFormat.F32,
        realtime: bool = False,
        max_lead_s: float = 0.5,
        finish: bool = True,
    ) -> AsyncIterator[Message]:
        """Streams ``audio`` (frames, channels; it continues the session's audio at
        ``next_sample``) in blocks of ``block`` frames, each preceded by the ``detections`` with
        ``t`` before its end (the order ``avsep process`` reads them in), and yields what the
        server sends meanwhile. Paced in real time, or as fast as the session keeps up (at most
        ``max_lead_s`` of audio ahead of the last step). With ``finish`` it then sends
        ``finish`` and yields until the stream closes (the last message is :class:`Closed`);
        without, it returns once everything is sent, and a later ``feed`` goes on."""
        welcome = self.welcome
        if welcome is None:
            raise RuntimeError("the stream is not open (use `async with`)")
        a = np.asarray(audio)
        if a.ndim != 2 or a.shape[1] != welcome.channels:
            raise ValueError(
                f"audio shaped {a.shape}; the session takes {welcome.channels} channels"
            )
        rate = welcome.sample_rate
        side = sorted(detections, key=lambda d: d.t)
        step_samples = round(welcome.step_s * rate)
        lead = int(max_lead_s * rate)
        base = self.next_sample

        async def send_all() -> None:
            started = time.monotonic()
            k = 0
            sent_end = base
            for start in range(0, a.shape[0], max(1, block)):
                end = min(start + block, a.shape[0])
                if realtime:
                    await asyncio.sleep(max(0.0, end / rate - (time.monotonic() - started)))
                else:
                    await self._wait_for_steps(sent_end, lead, step_samples)
                while k < len(side) and side[k].t < (base + end) / rate:
                    await self.send_detections(side[k])
                    k += 1
                await self.send_audio(a[start:end], base + start, fmt)
                sent_end = base + end
            for d in side[k:]:
                await self.send_detections(d)
            if finish:
                await self.finish()

        sender: asyncio.Task[None] = asyncio.create_task(send_all())
        try:
            while True:
                if sender.done() and (not finish or sender.exception() is not None):
                    # Everything is sent (without `finish`, the feed is over), or sending failed
                    # and `await` raises the failure.
                    await sender
                    return
                nxt: asyncio.Future[Message | None] = asyncio.ensure_future(self.next_message())
                waiting: set[asyncio.Future[Any]] = {nxt} if sender.done() else {nxt, sender}
                await asyncio.wait(waiting, return_when=asyncio.FIRST_COMPLETED)
                if not nxt.done():
                    nxt.cancel()
                    await asyncio.gather(nxt, return_exceptions=True)
                    continue
                msg = nxt.result()
                if msg is None:
                    break
                yield msg
            await sender
        finally:
            if not sender.done():
                sender.cancel()
