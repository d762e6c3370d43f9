"""Embedded MQTT broker (amqtt, pure Python) for tests and demos.

``python -m comems4build_ros.mqtt.broker --port P [--host H] [--users FILE] [--cert C --key K]``
runs an amqtt broker until SIGINT/SIGTERM and prints ``broker ready <host>:<port>`` on
stdout once it listens. ``--users`` is a password file of ``user:<argon2 hash>`` lines
(write one with :func:`write_password_file`); without it anonymous clients are allowed.
``--login-file FILE --user NAME ...`` gives the users NAME the password in the first line
of FILE (a per-run secret of mode 0600: :func:`comems4build_ros.wire.tokens.read_token_file`);
the broker hashes it into a users file of its own, in a private temporary directory, so no
password stands on a command line or in a file others can read. With neither option
anonymous clients are allowed.
``--cert``/``--key`` make the listener TLS (``mqtts://``). The launcher starts it when a
run has a plant behind MQTT and no broker URL is given; in real use any broker
(Mosquitto, Home Assistant's add-on) is given by URL instead.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import os
import signal
import socket
import sys
import tempfile
from pathlib import Path
from typing import Any

#: Plugin of amqtt's file-based authentication and of anonymous access.
FILE_AUTH_PLUGIN = "amqtt.plugins.authentication.FileAuthPlugin"
ANON_AUTH_PLUGIN = "amqtt.plugins.authentication.AnonymousAuthPlugin"


def broker_config(host: str, port: int, users: str | None = None, cert: str | None = None,
                  key: str | None = None) -> dict[str, Any]:
    """amqtt broker configuration: one TCP listener, anonymous or password-file access."""
    listener: dict[str, Any] = {"type": "tcp", "bind": f"{host}:{port}"}
    if cert:
        listener.update(ssl=True, certfile=cert, keyfile=key)
    plugins: dict[str, Any] = (
        {FILE_AUTH_PLUGIN: {"password_file": users}} if users else {ANON_AUTH_PLUGIN: {"allow_anonymous": True}}
    )
    return {"listeners": {"default": listener}, "plugins": plugins}


def write_password_file(path: str | Path, users: dict[str, str]) -> Path:
    """Write an amqtt password file (``user:<argon2 hash>`` lines) for ``users`` (name -> password)."""
    from pwdlib import PasswordHash
    from pwdlib.hashers.argon2 import Argon2Hasher

    hasher = PasswordHash((Argon2Hasher(),))
    path = Path(path)
    path.write_text("".join(f"{u}:{hasher.hash(p)}\n" for u, p in users.items()), encoding="utf-8")
    return path


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free right now on ``host``."""
    with contextlib.closing(socket.socket(socket.AF_INET, socket.SOCK_STREAM)) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


async def serve(config: dict[str, Any], ready_line: str) -> None:
    """Run the broker until SIGINT or SIGTERM."""
    from amqtt.broker import Broker

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    broker = Broker(config)
    await broker.start()
    print(ready_line, flush=True)
    await stop.wait()
    await broker.shutdown()


def main(argv: list[str] | None = None) -> int:
    """Entry point (see the module docstring); exit code 2 for bad options."""
    ap = argparse.ArgumentParser(prog="comems4build-broker", description="embedded MQTT broker (amqtt)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--users", default=None, help="password file (user:<argon2 hash> lines)")
    ap.add_argument("--login-file", default=None, help="per-run secret (mode 0600): the password of every --user")
    ap.add_argument("--user", action="append", default=[], help="user whose password is in --login-file")
    ap.add_argument("--cert", default=None, help="TLS certificate (PEM)")
    ap.add_argument("--key", default=None, help="TLS private key (PEM)")
    args = ap.parse_args(argv)
    for opt in ("users", "cert", "key"):
        value = getattr(args, opt)
        if value and not Path(value).is_file():
            print(f"broker: error: --{opt} {value}: no such file", file=sys.stderr)
            return 2
    if bool(args.cert) != bool(args.key):
        print("broker: error: --cert and --key go together", file=sys.stderr)
        return 2
    if bool(args.login_file) != bool(args.user) or (args.login_file and args.users):
        print("broker: error: --login-file and --user go together, and not with --users", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.WARNING, format="[broker] %(levelname)s %(name)s: %(message)s")
    logging.getLogger("transitions").setLevel(logging.ERROR)
    with tempfile.TemporaryDirectory(prefix="comems4build_broker_") as tmp:  # mode 0700
        users = args.users
        if args.login_file:
            from comems4build_ros.wire.tokens import read_token_file

            try:
                password = str(read_token_file(args.login_file))
            except ValueError as exc:
                print(f"broker: error: --login-file: {exc}", file=sys.stderr)
                return 2
            users = str(write_password_file(Path(tmp) / "users", {u: password for u in args.user}))
            os.chmod(users, 0o600)
        config = broker_config(args.host, args.port, users, args.cert, args.key)
        try:
            asyncio.run(serve(config, f"broker ready {args.host}:{args.port}"))
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
