"""``dsim serve [--db PATH] [--host 127.0.0.1] [--port N]``: registered on the
``dsim`` command line through the ``dsim.commands`` entry point, so that the
master imports nothing of the web front end (which is an optional extra)."""
from __future__ import annotations

import ipaddress
import os
import secrets
import socket

from dsim import InputError

#: the packages of the ``serve`` extra, by import name
NEEDED = ("fastapi", "uvicorn", "jinja2", "multipart")


def loopback(host: str) -> bool:
    """Whether ``host`` is reachable from this machine only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _missing() -> list[str]:
    from importlib.util import find_spec

    return [name for name in NEEDED if find_spec(name) is None]


def _bind(host: str, port: int) -> socket.socket:
    """A listening socket on ``host``:``port`` (0: a free port), bound here rather than
    by uvicorn so that the printed address has the real port and a port in use is one
    line."""
    try:
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
        listening = socket.socket(family, socket.SOCK_STREAM)
        listening.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listening.bind((host, port))
        listening.listen(128)
    except OSError as error:
        raise InputError(f"--host {host} --port {port}: cannot listen there "
                         f"({error.strerror or error})") from None
    return listening


def serve(args) -> int:
    """Run the server until Ctrl-C."""
    missing = _missing()
    if missing:
        raise InputError(f"dsim serve needs the optional dependencies ({', '.join(missing)} "
                         "missing): pip install 'dsim[serve]'")
    if not 0 <= args.port <= 65535:
        raise InputError(f"--port {args.port}: not a port number (0 to 65535)")
    token = args.token
    if not loopback(args.host) and not token:
        token = secrets.token_urlsafe(24)
    import uvicorn

    # here, not at the top: every `dsim` command reads this module to register
    # `dsim serve`, and the web application's imports take a third of a second
    from dsim.serve.app import accepted_hosts, create_app

    listening = _bind(args.host, args.port)
    port = listening.getsockname()[1]  # the one the system chose for --port 0
    try:  # a second server on this database: one line with the first one's pid
        app = create_app(args.db, token=token, slots=args.jobs,
                         max_upload=int(args.max_upload_mb * 2**20),
                         hosts=accepted_hosts(args.host, port))
    except InputError:
        listening.close()
        raise
    config = uvicorn.Config(app, host=args.host, port=port, log_level="warning")
    server = uvicorn.Server(config)
    shown = f"[{args.host}]" if ":" in args.host else args.host
    address = f"http://{shown}:{port}/"
    print(f"dsim serve: database {os.path.abspath(args.db)}")
    print(f"dsim serve: open {address}" + (f"?token={token}" if token else ""), flush=True)
    if token and not args.token:
        print("dsim serve: bound beyond this machine, so every request needs this token",
              flush=True)
    hosts = accepted_hosts(args.host, port)
    print("dsim serve: answers requests for " + (", ".join(hosts) if hosts else
          "any host name (with the token)"), flush=True)
    server.run(sockets=[listening])
    return 0


def register_command(commands) -> None:
    """Add ``dsim serve`` to the command line (entry point ``dsim.commands``)."""
    parser = commands.add_parser(
        "serve", help="a model database and web front end: upload, assemble, run, watch, "
                      "compare (needs the extra dsim[serve])")
    parser.add_argument("--db", default="dsim-serve.sqlite",
                        help="the database file, created on first use; files go to a folder "
                             "beside it (default: dsim-serve.sqlite)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to bind (default 127.0.0.1: this machine only; any "
                             "other needs a token)")
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765)")
    parser.add_argument("--token", help="the token requests must carry (default: none on "
                                        "127.0.0.1, else a new random one, printed)")
    parser.add_argument("--jobs", type=int, default=2, help="runs at once (default 2)")
    parser.add_argument("--max-upload-mb", type=float, default=512,
                        help="largest upload in MiB (default 512)")
    parser.set_defaults(handler=serve)
