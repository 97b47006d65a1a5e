"""A real `avsep serve` on a free port (the debug binary the cargo tests build, or AVSEP_BIN),
a scene made with `avsep simulate`, and its offline run with `avsep process`."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def avsep_bin() -> Path:
    if "AVSEP_BIN" in os.environ:
        return Path(os.environ["AVSEP_BIN"])
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    if not target.is_absolute():
        target = REPO / target
    return target / "debug" / "avsep"


@pytest.fixture(scope="session")
def avsep() -> Path:
    b = avsep_bin().resolve()
    if not b.exists():
        pytest.fail(f"{b} not found: build it with `cargo build` (or set AVSEP_BIN)")
    return b


def run(*args: object) -> None:
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{args}: {r.stdout}\n{r.stderr}"


@pytest.fixture(scope="session")
def server(avsep: Path) -> Iterator[str]:
    """The server's URL. No Zenoh: its default port is fixed, and tests run concurrently."""
    p = subprocess.Popen(
        [avsep, "serve", "--bind", "127.0.0.1:0", "--no-zenoh"],
        stdout=subprocess.PIPE,
        env={**os.environ, "AVSEP_LOG": "warn"},
        text=True,
    )
    assert p.stdout is not None
    line = p.stdout.readline()
    assert line.startswith("listening on http://"), line
    yield line.strip().removeprefix("listening on ")
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=30) == 0


@pytest.fixture(scope="session")
def scene(avsep: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("scene")
    run(avsep, "simulate", "--preset", "uca8", "--seed", 7, "--speakers", 2, "--duration", 2,
        "--out", d)
    return d


@pytest.fixture(scope="session")
def settings() -> dict[str, int]:
    """Pipeline settings of the sessions and of the offline run they are compared with."""
    return {"seed": 5}


@pytest.fixture(scope="session")
def offline(
    avsep: Path, scene: Path, settings: dict[str, int], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    d = tmp_path_factory.mktemp("offline")
    cfg = d / "settings.toml"
    cfg.write_text("".join(f"{k} = {v}\n" for k, v in settings.items()))
    run(avsep, "process", scene, "--out", d / "out", "--config", cfg)
    return d / "out"
