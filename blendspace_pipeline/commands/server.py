"""`blendspace server start|stop|status`: the resident build server (see `blendspace_pipeline.server`).

While a server runs, `blendspace build`, `check` and the other commands typed in a shell (or run by
a pre-commit hook) start in a process forked from it, with everything already imported, instead of
paying Python's imports each time. One server per user and installation; it stops by itself
after `--idle-timeout` seconds without a command, and as soon as the installed code changes.
`BLENDSPACE_NO_SERVER=1` makes a command ignore it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from typing import Any

from blendspace_pipeline.errors import EXIT_DIAGNOSTICS, EXIT_INPUT, EXIT_OK

HELP = "start, stop or query the build server that keeps the tool loaded between commands"
START_SECONDS = 120.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("start", "stop", "status"))
    parser.add_argument(
        "--idle-timeout",
        type=float,
        default=3 * 3600.0,
        metavar="SECONDS",
        help="stop after this long without a command (start; default 3 hours)",
    )
    parser.add_argument(
        "--foreground", action="store_true", help="serve in this process until Ctrl-C (start)"
    )


def run(args: argparse.Namespace) -> int:
    from blendspace_pipeline.server import address, client

    if not address.supported():
        sys.stderr.write(
            "blendspace server: not available on this platform (Linux only: it forks without exec); "
            "commands run in their own process\n"
        )
        return EXIT_INPUT
    if args.action == "status":
        return _status(client.ask("status"))
    if args.action == "stop":
        return _stop(client)
    if args.idle_timeout <= 0:
        sys.stderr.write("blendspace server: --idle-timeout must be more than 0 seconds\n")
        return EXIT_INPUT
    running = client.ask("status")
    if running is not None and running.get("matches") and running.get("current"):
        print(f"blendspace server: already running (pid {running['pid']}) on {running['socket']}")
        return EXIT_OK
    if running is not None:  # an older build of the tool, or another sys.path: replace it
        _stop(client, quiet=True)
    if args.foreground:
        from blendspace_pipeline.server.daemon import serve

        return serve(args.idle_timeout)
    return _start_background(args.idle_timeout, address, client)


def _start_background(idle_timeout: float, address: Any, client: Any) -> int:
    folder = address.server_dir()
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    problem = address.private_problem(folder)
    if problem is not None:
        sys.stderr.write(f"blendspace server: {problem}; set BLENDSPACE_SERVER_DIR to a private folder\n")
        return EXIT_INPUT
    log = address.log_path()
    with open(log, "w", encoding="utf-8") as stream:
        process = subprocess.Popen(
            [sys.executable, "-m", "blendspace_pipeline.server.daemon", "--idle-timeout", str(idle_timeout)],
            stdin=subprocess.DEVNULL,
            stdout=stream,
            stderr=stream,
            start_new_session=True,  # not killed with this shell's process group, nor by its Ctrl-C
        )
    deadline = time.monotonic() + START_SECONDS
    while time.monotonic() < deadline:
        answer = client.ask("status")
        if answer is not None and answer.get("pid") == process.pid:
            print(f"blendspace server: started (pid {process.pid}) on {answer['socket']}")
            return EXIT_OK
        if process.poll() is not None:
            break
        time.sleep(0.05)
    else:
        process.terminate()
    tail = log.read_text(encoding="utf-8", errors="replace").strip().splitlines()[-5:]
    sys.stderr.write("blendspace server: did not start; its log ends with:\n" + "\n".join(tail) + "\n")
    return EXIT_DIAGNOSTICS


def _status(answer: dict[str, Any] | None) -> int:
    if answer is None:
        print("blendspace server: not running (commands run in their own process)")
        return EXIT_DIAGNOSTICS
    uptime = time.time() - float(answer["started"])
    print(
        f"blendspace server: running (pid {answer['pid']}) on {answer['socket']}, up {uptime:.0f} s, "
        f"{answer['served']} command(s) served, stops after {answer['idle_timeout']:.0f} s idle"
    )
    if not answer.get("current"):
        print("  its code changed on disk: it stops at the next command; run `blendspace server start`")
    elif not answer.get("matches"):
        print(
            "  it does not serve this shell: the interpreter or sys.path (PYTHONPATH) differs; "
            "commands here run in their own process"
        )
    return EXIT_OK


def _stop(client: Any, *, quiet: bool = False) -> int:
    answer = client.ask("status")
    if answer is None:
        if not quiet:
            print("blendspace server: not running")
        return EXIT_OK
    client.ask("stop")
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and client.ask("status") is not None:
        time.sleep(0.05)
    if not quiet:
        print(f"blendspace server: stopped (pid {answer['pid']})")
    return EXIT_OK
