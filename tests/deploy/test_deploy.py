"""deploy/ checked without a container engine: the Dockerfile, the compose file and the
Kubernetes manifests agree on the image name, the ports the server config binds, the config
path and the health endpoints; the example config (with the environment each deployment adds)
parses with `avsep serve --config FILE --print-config`; a server started with it answers its
health endpoints; the systemd unit passes `systemd-analyze verify` and its security review."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import tomllib
import urllib.request
from pathlib import Path
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
CONFIG_PATH = "/etc/avsep/avsep.toml"


def avsep_bin() -> Path:
    if "AVSEP_BIN" in os.environ:
        return Path(os.environ["AVSEP_BIN"])
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return (target if target.is_absolute() else REPO / target) / "debug" / "avsep"


@pytest.fixture(scope="module")
def avsep() -> Path:
    b = avsep_bin().resolve()
    if not b.exists():
        pytest.fail(f"{b} not found: build it with `cargo build` (or set AVSEP_BIN)")
    return b


def config() -> dict[str, Any]:
    return tomllib.loads((DEPLOY / "avsep.toml").read_text())


def port_of(addr: str) -> int:
    return int(addr.rsplit(":", 1)[1])


def compose() -> dict[str, Any]:
    c: dict[str, Any] = yaml.safe_load((DEPLOY / "compose.yaml").read_text())
    return c


def k8s() -> dict[tuple[str, str], dict[str, Any]]:
    docs: dict[tuple[str, str], dict[str, Any]] = {}
    for f in sorted((DEPLOY / "k8s").glob("*.yaml")):
        for d in yaml.safe_load_all(f.read_text()):
            if d and "metadata" in d:
                docs[(d["kind"], d["metadata"]["name"])] = d
    return docs


def replicas() -> dict[str, dict[str, Any]]:
    return {k: v for k, v in compose()["services"].items() if k.startswith("avsep")}


def env_of(container: dict[str, Any]) -> dict[str, str]:
    return {e["name"]: str(e["value"]) for e in container.get("env", []) if "value" in e}


def avsep_container() -> dict[str, Any]:
    c: dict[str, Any] = k8s()[("Deployment", "avsep")]["spec"]["template"]["spec"]["containers"][0]
    return c


def dockerfile() -> str:
    return (DEPLOY / "Dockerfile").read_text()


def test_one_image_name_everywhere() -> None:
    tags = set(re.findall(r"docker build .*-t (\S+)", dockerfile()))
    assert len(tags) == 1, tags
    (image,) = tags
    assert {s["image"] for s in replicas().values()} == {image}
    assert len(replicas()) == 2
    assert avsep_container()["image"] == image
    router = compose()["services"]["zenoh-router"]["image"]
    k8s_router = k8s()[("Deployment", "zenoh-router")]["spec"]["template"]["spec"]["containers"]
    assert router.startswith("eclipse/zenoh") and k8s_router[0]["image"] == router


def test_ports_follow_the_server_config() -> None:
    cfg = config()
    http = port_of(cfg["bind"])
    zenoh = port_of(cfg["zenoh"]["listen"][0])
    exposed = {int(p) for line in re.findall(r"^EXPOSE (.+)$", dockerfile(), re.M) for p in line.split()}
    assert {http, zenoh} <= exposed
    host_ports = []
    for name, s in replicas().items():
        (mapping,) = s["ports"]
        host, container = str(mapping).split(":")
        assert int(container) == http, name
        host_ports.append(int(host))
    assert len(set(host_ports)) == 2, "each replica has its own HTTP port"

    c = avsep_container()
    ports = {p["name"]: p["containerPort"] for p in c["ports"]}
    assert ports == {"http": http}
    svc = k8s()[("Service", "avsep")]["spec"]["ports"][0]
    assert svc["targetPort"] in ("http", http) and svc["port"] == http
    for probe in ("readinessProbe", "livenessProbe"):
        assert c[probe]["httpGet"]["port"] in ("http", http)


def test_replicas_join_the_router_as_zenoh_clients() -> None:
    services = compose()["services"]
    listen = services["zenoh-router"]["command"]
    router_port = port_of(listen[listen.index("--listen") + 1])
    assert services["zenoh-router"]["ports"] == [f"{router_port}:{router_port}"]
    kr = k8s()[("Deployment", "zenoh-router")]["spec"]["template"]["spec"]["containers"][0]
    assert kr["args"] == listen
    ks = k8s()[("Service", "zenoh-router")]["spec"]["ports"][0]
    assert ks["port"] == router_port and kr["ports"][0]["containerPort"] == router_port
    for env in [s["environment"] for s in replicas().values()] + [env_of(avsep_container())]:
        assert env["AVSEP_ZENOH_MODE"] in ("client", "peer")
        assert env["AVSEP_ZENOH_CONNECT"] == f"tcp/zenoh-router:{router_port}"
    for name in replicas():
        assert "zenoh-router" in compose()["services"][name]["depends_on"]


def test_one_config_path_everywhere() -> None:
    df = dockerfile()
    assert f"COPY deploy/avsep.toml {CONFIG_PATH}" in df
    assert f"ENV AVSEP_CONFIG={CONFIG_PATH}" in df
    for name, s in replicas().items():
        assert s["environment"]["AVSEP_CONFIG"] == CONFIG_PATH, name
        assert f"./avsep.toml:{CONFIG_PATH}:ro" in s["volumes"], name
    c = avsep_container()
    assert env_of(c)["AVSEP_CONFIG"] == CONFIG_PATH
    (mount,) = c["volumeMounts"]
    cm = k8s()[("ConfigMap", "avsep-config")]
    assert Path(mount["mountPath"]) / "avsep.toml" == Path(CONFIG_PATH)
    volume = k8s()[("Deployment", "avsep")]["spec"]["template"]["spec"]["volumes"][0]
    assert volume["name"] == mount["name"] and volume["configMap"]["name"] == "avsep-config"
    assert cm["data"]["avsep.toml"] == (DEPLOY / "avsep.toml").read_text(), (
        "the ConfigMap holds deploy/avsep.toml verbatim"
    )
    unit = (DEPLOY / "avsep.service").read_text()
    assert f"ExecStart=/usr/local/bin/avsep serve --config {CONFIG_PATH}" in unit


def test_the_memory_budget_fits_the_container() -> None:
    budget_mib = config()["limits"]["max_memory_mb"]
    limit = avsep_container()["resources"]["limits"]["memory"]
    units = {"Mi": 1, "Gi": 1024}
    limit_mib = int(limit[:-2]) * units[limit[-2:]]
    assert 0 < budget_mib <= 0.8 * limit_mib, "leave the process room beyond the pipelines"


def test_health_endpoints() -> None:
    c = avsep_container()
    assert c["readinessProbe"]["httpGet"]["path"] == "/readyz"
    assert c["livenessProbe"]["httpGet"]["path"] == "/healthz"
    assert "/healthz" in re.search(r"HEALTHCHECK[\s\S]*?\n(?!\s)", dockerfile()).group(0)  # type: ignore[union-attr]
    for s in replicas().values():
        assert "/readyz" in " ".join(s["healthcheck"]["test"])


def test_images_build_in_rust_and_run_slim_as_a_non_root_user() -> None:
    stages = re.findall(r"^FROM (\S+)(?: AS (\S+))?$", dockerfile(), re.M)
    assert stages[0][0].startswith("rust:") and stages[0][1] == "build"
    assert re.fullmatch(r"debian:[a-z]+-slim", stages[-1][0])
    user = re.findall(r"^USER (\S+)$", dockerfile(), re.M)
    assert user and user[-1].split(":")[0] not in ("0", "root")
    assert avsep_container()["securityContext"]["readOnlyRootFilesystem"] is True
    pod = k8s()[("Deployment", "avsep")]["spec"]["template"]["spec"]
    assert pod["securityContext"]["runAsUser"] == int(user[-1].split(":")[0])
    for src in re.findall(r"^COPY (?!--from)(\S+) \S+$", dockerfile(), re.M):
        assert (REPO / src).exists(), f"COPY {src}: no such file"


def print_config(avsep: Path, env: dict[str, str]) -> dict[str, Any]:
    r = subprocess.run(
        [avsep, "serve", "--config", DEPLOY / "avsep.toml", "--print-config"],
        capture_output=True,
        text=True,
        env={k: v for k, v in {**os.environ, **env}.items() if k != "AVSEP_CONFIG"},
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    return tomllib.loads(r.stdout)


def test_the_config_parses_alone_and_with_each_deployments_environment(avsep: Path) -> None:
    alone = print_config(avsep, {})
    assert alone["bind"] == config()["bind"]
    assert alone["zenoh"]["mode"] == "peer"
    envs = [{k: str(v) for k, v in s["environment"].items()} for s in replicas().values()]
    for env in envs + [env_of(avsep_container())]:
        shown = print_config(avsep, {k: v for k, v in env.items() if k != "AVSEP_CONFIG"})
        assert shown["zenoh"]["mode"] == env["AVSEP_ZENOH_MODE"]
        assert shown["zenoh"]["connect"] == [env["AVSEP_ZENOH_CONNECT"]]
        assert shown["zenoh"]["listen"] == [env["AVSEP_ZENOH_LISTEN"]]
        assert shown["limits"]["max_sessions"] == config()["limits"]["max_sessions"]


def test_a_server_with_the_config_answers_health_and_readiness(avsep: Path) -> None:
    # Free ports instead of the config's fixed ones (tests run concurrently).
    p = subprocess.Popen(
        [avsep, "serve", "--config", DEPLOY / "avsep.toml", "--bind", "127.0.0.1:0", "--no-zenoh"],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "AVSEP_LOG": "warn"},
    )
    try:
        assert p.stdout is not None
        line = p.stdout.readline()
        url = line.strip().removeprefix("listening on ")
        for path in ("/healthz", "/readyz"):
            with urllib.request.urlopen(url + path, timeout=10) as r:
                assert r.status == 200, path
    finally:
        p.send_signal(signal.SIGTERM)
        assert p.wait(timeout=30) == 0


def test_systemd_unit_verifies_and_is_hardened(avsep: Path, tmp_path: Path) -> None:
    if shutil.which("systemd-analyze") is None:
        pytest.skip("systemd-analyze is not installed (scripts/setup installs the systemd package)")
    unit = (DEPLOY / "avsep.service").read_text()
    for key in ("DynamicUser=yes", "ProtectSystem=strict", "NoNewPrivileges=yes", "ProtectHome=yes"):
        assert key in unit.splitlines(), key
    # verify checks that ExecStart's binary exists: point it at the one just built.
    local = tmp_path / "avsep.service"
    local.write_text(unit.replace("ExecStart=/usr/local/bin/avsep", f"ExecStart={avsep}"))
    r = subprocess.run(["systemd-analyze", "verify", local], capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr.strip(), r.stderr
    # The security review's exposure level (0 = locked down, 10 = none) must stay at most 2.0.
    r = subprocess.run(
        ["systemd-analyze", "security", "--offline=true", "--threshold=20", local],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    assert "Overall exposure level" in r.stdout
