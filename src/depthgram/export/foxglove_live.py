"""A live Foxglove WebSocket server: each frame's results as they are computed, on the MCAP file's topics.

``depthgram view INPUT --foxglove`` plays a recording through the pipeline and publishes every
frame here; Foxglove connects with *Open connection > Foxglove WebSocket* at
``ws://HOST:PORT``. The topics, schemas and messages are those of the MCAP file
(:mod:`depthgram.export.messages`, built by the same code), so a layout made for one opens the
other. The server is the ``foxglove-sdk`` package's (extra ``depthgram[foxglove]``).
"""

from __future__ import annotations

import json
import time
from typing import TYPE_CHECKING, Any

from depthgram._optional import needs_extra
from depthgram.errors import InputError

if TYPE_CHECKING:
    from depthgram.pipeline import SceneResult

__all__ = ["FoxgloveServer"]


class FoxgloveServer:
    """Publish :class:`~depthgram.pipeline.SceneResult` frames to Foxglove over its WebSocket protocol.

    Parameters
    ----------
    host : str
        Address to listen on (default: this machine only).
    port : int
        TCP port; 0 picks a free one (see :attr:`port`).
    name : str
        The server's name, shown by Foxglove.
    ttc_warn_s : float
        A frame with an object whose time to collision is under this (s) logs its sentence as a
        WARNING.

    Notes
    -----
    A frame's messages are built only while a client is subscribed to one of the topics:
    outlines and 3-D boxes cost a few milliseconds per frame that nobody would see.
    """

    def __init__(
        self, host: str = "127.0.0.1", port: int = 8765, *, name: str = "depthgram", ttc_warn_s: float = 3.0
    ) -> None:
        with needs_extra("foxglove", "the live Foxglove server (view --foxglove)"):
            import foxglove

            from depthgram.export.messages import MESSAGE_TYPES, SCENE_SCHEMA, TOPICS, frame_messages, protobuf_schema

        self._frame_messages = frame_messages
        self.ttc_warn_s = ttc_warn_s
        self.published = 0
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name=name, host=host, port=port, context=self._context)
        except Exception as exc:  # the SDK raises its own error type with the OS's message
            raise InputError(
                f"cannot start the Foxglove server on {host}:{port} ({exc}): "
                "is the port in use? choose another with --port N (--port 0 picks a free one)"
            ) from None
        self._channels: dict[str, Any] = {}
        for topic, cls in MESSAGE_TYPES.items():
            schema = foxglove.Schema(name=TOPICS[topic], encoding="protobuf", data=protobuf_schema(cls))
            self._channels[topic] = foxglove.Channel(
                topic, schema=schema, message_encoding="protobuf", context=self._context
            )
        scene = foxglove.Schema(
            name=TOPICS["/depthgram/scene"], encoding="jsonschema", data=json.dumps(SCENE_SCHEMA).encode()
        )
        self._channels["/depthgram/scene"] = foxglove.Channel(
            "/depthgram/scene", schema=scene, message_encoding="json", context=self._context
        )

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return int(self._server.port)

    @property
    def watched(self) -> bool:
        """Whether a client is subscribed to at least one topic."""
        return any(ch.has_sinks() for ch in self._channels.values())

    def publish(self, result: SceneResult, t_ns: int | None = None) -> bool:
        """Publish one frame's messages, stamped ``t_ns`` (ns; default: now); False when nobody watches."""
        if not self.watched:
            return False
        t = time.time_ns() if t_ns is None else t_ns
        for m in self._frame_messages(result, t, self.ttc_warn_s):
            self._channels[m.topic].log(m.encode(), log_time=t)
        self.published += 1
        return True

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        for ch in self._channels.values():
            ch.close()
        self._server.stop()

    def __enter__(self) -> FoxgloveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
