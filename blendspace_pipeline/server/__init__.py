"""The build server: a resident process that keeps the tool imported, so a command starts warm.

`blendspace server start` runs it; while it listens, `build`, `check` and the other commands hand
their arguments, working folder, environment and standard streams to it, and a process forked
from it runs the command exactly as `blendspace` would, writing straight to the caller's terminal
(pants, Gradle and dmypy do the same, for the same reason: in Python, start-up and imports cost
more than a small rebuild). Without a server, or when it cannot answer, the command runs in the
calling process as always.

- `address`: where the socket lives and the fingerprint of the installed code (standard library
  only, so a client costs a few stat calls);
- `client`: forwards one command and relays Ctrl-C;
- `daemon`: the server loop (POSIX only: it needs `fork` and descriptor passing).
"""
