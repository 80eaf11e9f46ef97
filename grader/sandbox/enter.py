"""First process of a scenario's namespaces: join its cgroup, bring the loopback up, exec.

``unshare --net --pid --fork ... python -S enter.py [--procs FILE]... [--loopback] -- CMD...``

Runs as PID 1 of the scenario's new PID namespace, before the scenario child (``CMD``) replaces
it, so the scenario child and everything it starts are in the cgroup from their first
instruction (joining from the parent after ``Popen`` would race with the first fork). A new
network namespace starts with its loopback down; ``unshare`` does not raise it. Standard library
only and started with ``-S``: it costs about 15 ms per scenario.
"""

import fcntl
import os
import socket
import struct
import sys

SIOCGIFFLAGS = 0x8913
SIOCSIFFLAGS = 0x8914
IFF_UP = 0x1


def loopback_up() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        ifreq = struct.pack("16sH14x", b"lo", 0)
        flags = struct.unpack("16sH14x", fcntl.ioctl(s.fileno(), SIOCGIFFLAGS, ifreq))[1]
        fcntl.ioctl(s.fileno(), SIOCSIFFLAGS, struct.pack("16sH14x", b"lo", flags | IFF_UP))


def main(argv: list[str]) -> int:
    if "--" not in argv:
        print("usage: enter.py [--procs FILE]... [--loopback] -- CMD...", file=sys.stderr)
        return 2
    split = argv.index("--")
    opts, cmd = argv[:split], argv[split + 1:]
    pid = str(os.getpid()).encode()
    i = 0
    while i < len(opts):
        if opts[i] == "--procs":
            fd = os.open(opts[i + 1], os.O_WRONLY)
            try:
                os.write(fd, pid)
            finally:
                os.close(fd)
            i += 2
        elif opts[i] == "--loopback":
            loopback_up()
            i += 1
        else:
            print(f"enter.py: unknown option {opts[i]}", file=sys.stderr)
            return 2
    os.execvp(cmd[0], cmd)
    return 127


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
