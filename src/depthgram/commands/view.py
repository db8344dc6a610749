"""depthgram view: play a recording through the pipeline in a live page in the browser."""

from __future__ import annotations

import argparse
import socket
import sys

from depthgram.commands._common import add_config_arguments, add_source_arguments

NAME = "view"
HELP = "live viewer in the browser: frames with outlines, sentence, tree, tracks, action plan and sound"

_LOOPBACK = ("127.0.0.1", "localhost", "::1")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.epilog = (
        "--fps also sets the playback rate at speed 1 (default: the recording's own rate, else 30 "
        "frames/s). One server plays one recording; every open page shares its playback controls."
    )
    add_source_arguments(p)
    add_config_arguments(p)
    g = p.add_argument_group("viewer")
    g.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only). Any other address "
        "needs --allow-host or an access token (printed in the address, made up when not given)",
    )
    g.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a host name (or address) pages reach this server by, beyond loopback; repeatable",
    )
    g.add_argument(
        "--token",
        default=None,
        help="access token required of every request (the page keeps it in a cookie once opened "
        "with ?token=...); default: made up when --host is not loopback and no --allow-host",
    )
    g.add_argument("--port", type=int, default=8765, help="TCP port (0 picks a free one)")
    g.add_argument("--no-browser", action="store_true", help="do not open a browser window")
    g.add_argument("--speed", type=float, default=1.0, help="initial playback speed factor, in (0, 16]")
    g.add_argument("--no-loop", action="store_true", help="pause at the end instead of starting over")
    g.add_argument(
        "--compress",
        action="store_true",
        help="compress each frame's depth and labels (about 3 x smaller, for slow links)",
    )
    g.add_argument("--jpeg", action="store_true", help=argparse.SUPPRESS)  # deprecated: --compress
    g.add_argument(
        "--foxglove",
        action="store_true",
        help="serve the results to Foxglove (Open connection > Foxglove WebSocket, ws://HOST:PORT) "
        "instead of the browser page: the topics of describe --mcap (needs depthgram[foxglove])",
    )


def access(host: str, allow_host: list[str], token: str | None) -> tuple[tuple[str, ...] | None, str | None]:
    """Host names to accept (None: any) and the access token (None: none) for ``--host``.

    On loopback only this machine can connect, and checking the ``Host`` header against the
    loopback names is enough against other web sites (DNS rebinding). On any other address the
    whole network can send any ``Host``: the names users reach the server by must be given, or
    every request must carry a token (made up here when none is given).
    """
    import secrets

    from depthgram.views.guard import LOOPBACK_HOSTS

    if host in _LOOPBACK or allow_host:
        names = LOOPBACK_HOSTS + tuple(h.strip().lower().strip("[]") for h in allow_host)
        return names, token
    return None, token or secrets.token_urlsafe(18)


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    import asyncio
    import threading
    import webbrowser

    from depthgram.commands._common import load_config, open_input, source_len
    from depthgram.errors import InputError

    if not 0 <= args.port <= 65535:
        raise InputError(f"--port must be in 0..65535, got {args.port}")
    if args.foxglove:
        return run_foxglove(args)
    from depthgram._optional import needs_extra

    with needs_extra("view", "the browser viewer"):
        import uvicorn

        from depthgram.views.guard import MAX_BODY_BYTES
        from depthgram.views.server import Player, ViewerConfig, create_app, recording_name

    sock = bind_port(args.host, args.port)
    src = open_input(args)
    cfg = load_config(args)
    if args.jpeg:
        print("depthgram view: --jpeg is deprecated (frames are no longer pictures): use --compress", file=sys.stderr)
    viewer = ViewerConfig(fps=args.fps, speed=args.speed, loop=not args.no_loop, compress=args.compress or args.jpeg)
    player = Player(
        lambda: iter(src),
        recording_name(args.input),
        cfg,
        viewer,
        frames=source_len(src),
        fps=getattr(src, "fps", None),
        seekable=not getattr(src, "live", False),
    )
    hosts, token = access(args.host, args.allow_host, args.token)
    if token is not None and args.token is None:
        print(
            f"depthgram view: listening on {args.host}: pages need the access token in the address "
            "printed below (or name the host with --allow-host)",
            file=sys.stderr,
        )
    server = uvicorn.Server(
        uvicorn.Config(
            create_app(player, allowed_hosts=hosts, token=token),
            host=args.host,
            port=args.port,
            log_level="warning",
            ws_max_size=MAX_BODY_BYTES,
            # frames are raw arrays: deflating each on the event loop
            # cost more than the whole pipeline (docs/design-notes.md, the viewer)
            ws_per_message_deflate=False,
        )
    )

    def announce() -> None:
        # The port is known only once the socket is bound (--port 0).
        while not server.started:
            if server.should_exit:
                return
            threading.Event().wait(0.05)
        port = server.servers[0].sockets[0].getsockname()[1] if server.servers else args.port
        host = f"[{args.host}]" if ":" in args.host else args.host
        url = f"http://{host}:{port}/" + (f"?token={token}" if token else "")
        print(f"depthgram view: playing {args.input} at {url} (Ctrl-C stops)", file=sys.stderr)
        if not args.no_browser:
            webbrowser.open(url)

    threading.Thread(target=announce, daemon=True).start()
    asyncio.run(server.serve(sockets=[sock]))
    return 0


def run_foxglove(args: argparse.Namespace) -> int:
    """Play the recording through the pipeline in real time and publish each frame to Foxglove.

    Frames are dropped by the rule of ``depthgram run`` and the browser viewer
    (:class:`depthgram.views.player.Pacer`); the recording starts again at its end unless
    ``--no-loop``. A frame is only turned into messages while a client is subscribed.
    """
    import gc
    import time

    from depthgram.commands._common import make_pipeline, open_input
    from depthgram.errors import InputError
    from depthgram.export.foxglove_live import FoxgloveServer
    from depthgram.pacing import Pacer
    from depthgram.sources.prefetch import prefetch
    from depthgram.views.player import check_speed

    speed = check_speed(args.speed)
    if args.host not in _LOOPBACK and not args.allow_host:
        # The Foxglove protocol has no access token: beyond loopback anyone could watch.
        print(
            f"depthgram view: --foxglove on {args.host}: anyone on the network can connect (the "
            "Foxglove protocol has no token)",
            file=sys.stderr,
        )
    src = open_input(args)
    pipe = make_pipeline(args)
    fps = float(args.fps or getattr(src, "fps", None) or 30.0)
    server = FoxgloveServer(args.host, args.port)
    host = f"[{args.host}]" if ":" in args.host else args.host
    print(
        f"depthgram view: serving {args.input} to Foxglove at ws://{host}:{server.port} "
        "(in Foxglove: Open connection > Foxglove WebSocket; Ctrl-C stops)",
        file=sys.stderr,
    )
    shown = dropped = 0
    try:
        while True:
            pacer = Pacer(1.0 / (fps * speed))
            pipe.reset()
            frames = prefetch(iter(src), ahead=2)
            any_frame = False
            fresh = True
            for frame in frames:
                any_frame = True
                if not fresh and pacer.late():
                    dropped += 1
                    pacer.advance()
                    continue
                wait = pacer.wait_s()
                if wait > 0:
                    time.sleep(wait)
                server.publish(pipe.process(frame))
                shown += 1
                if shown == 1:
                    gc.freeze()  # as run does: no full collection walks what is loaded by now
                if fresh:
                    # As in the browser viewer, the clock starts once the first frame is out:
                    # start-up costs (compiled kernels) are not a backlog to drop frames for.
                    pacer.start(pacer.clock() + pacer.period)
                    fresh = False
                else:
                    pacer.advance()
            if not any_frame:
                raise InputError(f"{args.input}: the recording has no frame")
            if args.no_loop or getattr(src, "live", False):
                break
    except KeyboardInterrupt:
        pass
    finally:
        gc.unfreeze()
        server.close()
    print(f"depthgram view: {shown} frames processed, {dropped} dropped, {server.published} published", file=sys.stderr)
    return 0


def bind_port(host: str, port: int) -> socket.socket:
    """Return a listening socket on ``host``:``port``, or an :class:`InputError` saying what to do.

    The viewer binds it itself (uvicorn then serves on it) so that a port in use is a one-line
    message instead of uvicorn's log and exit.
    """
    import errno

    from depthgram.errors import InputError

    try:
        infos = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise InputError(f"--host {host}: not an address of this machine ({exc.strerror})") from None
    family, kind, proto, _, addr = infos[0]
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(addr)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            raise InputError(
                f"port {port} on {host} is already in use (another depthgram view?): "
                "stop it, or choose another with --port N (--port 0 picks a free one)"
            ) from None
        if exc.errno == errno.EACCES:
            raise InputError(
                f"port {port} on {host}: permission denied (ports below 1024 need root): choose another with --port N"
            ) from None
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock
