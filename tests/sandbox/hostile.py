"""A hostile "student" program: ``python hostile.py MODE ARGS...``, one behaviour per mode.

Each mode prints one line per attempt (``OK``/``DENIED`` with the reason), so a test reads what
was tried and what the sandbox let through.
"""

import json
import os
import socket
import sys
import time


def writer(paths: list[str]) -> None:
    """Write, append to, and delete files at ``paths`` (other results, the rubric, our own bag)."""
    for p in paths:
        for what, fn in (("create", lambda: open(os.path.join(p, "pwned.txt") if os.path.isdir(p) else p + ".pwned", "w").write("x")),
                         ("append", lambda: open(p, "a").write("pwned")),
                         ("delete", lambda: os.remove(p))):
            try:
                fn()
                print(f"WRITE-OK {what} {p}", flush=True)
            except OSError as exc:
                print(f"WRITE-DENIED {what} {p} {exc.strerror}", flush=True)


def reader(paths: list[str]) -> None:
    print("ENV " + json.dumps(sorted(os.environ)), flush=True)
    print(f"ID uid={os.getuid()} cwd={os.getcwd()} home={os.environ.get('HOME')}", flush=True)
    for p in paths:
        try:
            data = open(p, "rb").read(64) if os.path.isfile(p) else os.listdir(p)
            print(f"READ-OK {p} {str(data)[:40]!r}", flush=True)
        except OSError as exc:
            print(f"READ-DENIED {p} {exc.strerror}", flush=True)
    for p in (os.environ.get("HOME", "/nonexistent"), os.environ.get("TMPDIR", "/nonexistent"), "/tmp"):
        try:
            open(os.path.join(p, "scratch.txt"), "w").write("mine")
            print(f"SCRATCH-OK {p}", flush=True)
        except OSError as exc:
            print(f"SCRATCH-DENIED {p} {exc.strerror}", flush=True)


def net(targets: list[str]) -> None:
    for target in targets:
        host, port = target.rsplit(":", 1)
        try:
            socket.create_connection((host, int(port)), timeout=3).close()
            print(f"NET-OK {target}", flush=True)
        except OSError as exc:
            print(f"NET-DENIED {target} {exc.strerror or exc}", flush=True)


def detach(token: str) -> None:
    """Double fork + setsid: a daemon that killpg and PR_SET_PDEATHSIG do not reach."""
    if os.fork() == 0:
        os.setsid()
        if os.fork() == 0:
            os.execv(sys.executable, [sys.executable, "-c", "import time\nwhile True: time.sleep(1)", token])
        os._exit(0)
    print("DETACHED", flush=True)
    while True:
        time.sleep(1)


def flood(mib: str) -> None:
    line = ("x" * 1023 + "\n") * 64
    for _ in range(int(mib) * 16):
        sys.stdout.write(line)
    sys.stdout.flush()
    print("FLOOD-DONE", file=sys.stderr, flush=True)
    while True:
        time.sleep(1)


def hog(mib: str) -> None:
    chunks = []
    for i in range(int(mib) // 64):
        chunks.append(bytearray(64 * 2**20))      # zero-filled: the pages are really touched
        print(f"HOG {(i + 1) * 64} MiB", flush=True)
    print("HOG-DONE", flush=True)
    while True:
        time.sleep(1)


def bomb(token: str) -> None:
    failed = 0
    children = 0
    for _ in range(2000):
        try:
            pid = os.fork()
        except OSError:
            failed += 1
            continue
        if pid == 0:        # a forked copy sleeps (it keeps the token in its command line); no exec:
            time.sleep(600)  # 60 fresh interpreters would fill the memory limit the hog tests
            os._exit(0)
        children += 1
    print(f"BOMB children={children} refused={failed}", flush=True)
    while True:
        time.sleep(1)


if __name__ == "__main__":
    mode, args = sys.argv[1], sys.argv[2:]
    {"writer": writer, "reader": reader, "net": net}.get(mode, lambda a: None)(args) if mode in (
        "writer", "reader", "net") else {"detach": detach, "flood": flood, "hog": hog, "bomb": bomb}[mode](*args)
    while True:
        time.sleep(1)
