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
    p.epilog = ("--fps also sets the playback rate at speed 1 (default: the recording's own rate, else 30 "
                "frames/s). One server plays one recording; every open page shares its playback controls.")
    add_source_arguments(p)
    add_config_arguments(p)
    g = p.add_argument_group("viewer")
    g.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only; the viewer has no login)")
    g.add_argument("--port", type=int, default=8765, help="TCP port (0 picks a free one)")
    g.add_argument("--no-browser", action="store_true", help="do not open a browser window")
    g.add_argument("--speed", type=float, default=1.0, help="initial playback speed factor, in (0, 16]")
    g.add_argument("--no-loop", action="store_true", help="pause at the end instead of starting over")
    g.add_argument("--jpeg", action="store_true", help="send frames as JPEG instead of PNG (smaller, softer)")


def run(args: argparse.Namespace) -> int:
    import asyncio
    import threading
    import webbrowser

    from depthgram.commands._common import load_config, open_input, source_len
    from depthgram.errors import InputError

    if not 0 <= args.port <= 65535:
        raise InputError(f"--port must be in 0..65535, got {args.port}")
    from depthgram._optional import needs_extra

    with needs_extra("view", "the browser viewer"):
        import uvicorn

        from depthgram.views.server import LOOPBACK_HOSTS, Player, ViewerConfig, create_app, recording_name

    sock = bind_port(args.host, args.port)
    src = open_input(args)
    cfg = load_config(args)
    viewer = ViewerConfig(fps=args.fps, speed=args.speed, loop=not args.no_loop,
                          image_format="jpeg" if args.jpeg else "png")
    player = Player(lambda: iter(src), recording_name(args.input), cfg, viewer,
                    frames=source_len(src), fps=getattr(src, "fps", None))
    if args.host not in _LOOPBACK:
        print(f"depthgram view: warning: listening on {args.host}: anyone who can reach this address can "
              "watch the recording and change the playback (there is no login)", file=sys.stderr)
    if args.host in _LOOPBACK:
        hosts: tuple[str, ...] | None = LOOPBACK_HOSTS
    elif args.host in ("0.0.0.0", "::", ""):
        hosts = None  # every address of the machine: any name may reach it
    else:
        hosts = (*LOOPBACK_HOSTS, args.host)
    server = uvicorn.Server(uvicorn.Config(create_app(player, allowed_hosts=hosts), host=args.host, port=args.port,
                                           log_level="warning"))

    def announce() -> None:
        # The port is known only once the socket is bound (--port 0).
        while not server.started:
            if server.should_exit:
                return
            threading.Event().wait(0.05)
        port = server.servers[0].sockets[0].getsockname()[1] if server.servers else args.port
        host = f"[{args.host}]" if ":" in args.host else args.host
        url = f"http://{host}:{port}/"
        print(f"depthgram view: playing {args.input} at {url} (Ctrl-C stops)", file=sys.stderr)
        if not args.no_browser:
            webbrowser.open(url)

    threading.Thread(target=announce, daemon=True).start()
    asyncio.run(server.serve(sockets=[sock]))
    return 0


def bind_port(host: str, port: int) -> socket.socket:
    """A listening socket on ``host``:``port``, or an :class:`InputError` saying what to do.

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
            raise InputError(f"port {port} on {host} is already in use (another depthgram view?): "
                             "stop it, or choose another with --port N (--port 0 picks a free one)") from None
        if exc.errno == errno.EACCES:
            raise InputError(f"port {port} on {host}: permission denied (ports below 1024 need root): "
                             "choose another with --port N") from None
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock

