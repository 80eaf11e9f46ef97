"""Test node: ignores SIGINT and SIGTERM, and starts a grandchild that sleeps (must still die)."""
import signal
import subprocess
import sys
import time

signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
child = subprocess.Popen([sys.executable, "-c", "import signal,time; signal.signal(signal.SIGINT, signal.SIG_IGN); time.sleep(600)"])
print(f"child {child.pid}", flush=True)
while True:
    time.sleep(1)
