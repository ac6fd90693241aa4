"""Start a real `ncbot robot serve` on a free loopback port for the serve and browser tests."""
from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def running_server(out: Path, *extra: str, ready_timeout: float = 240.0) -> Iterator[str]:
    """Yield the base URL of a server (loopback only) once its scene is warm; stop it by its pid afterwards."""
    port = free_port()
    env = {**os.environ, "VK_ICD_FILENAMES": os.environ.get("VK_ICD_FILENAMES", "/usr/share/vulkan/icd.d/lvp_icd.json")}
    log = open(out.parent / f"server-{port}.log", "w")
    process = subprocess.Popen([sys.executable, "-m", "ncbot", "robot", "serve", "--host", "127.0.0.1",
                                "--port", str(port), "--out", str(out), *extra], stdout=log, stderr=subprocess.STDOUT, env=env)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + ready_timeout
        while True:
            if process.poll() is not None:
                raise RuntimeError(f"the server exited with {process.returncode}: {(out.parent / f'server-{port}.log').read_text()[-2000:]}")
            with contextlib.suppress(httpx.HTTPError):
                if httpx.get(url + "/healthz", timeout=2).json().get("ready"):
                    break
            if time.monotonic() > deadline:
                raise TimeoutError(f"the server was not ready within {ready_timeout} s")
            time.sleep(0.5)
        yield url
        assert process.poll() is None, "the server died during the test"
    finally:
        process.terminate()
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
        log.close()
