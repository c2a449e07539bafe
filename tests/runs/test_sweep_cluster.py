"""``himit sweep --address`` against a real Ray cluster, started as a user starts one.

``ray start --head`` on the loopback address, on free ports, in its own temporary directory (so
that it leaves no address in /tmp/ray for another Ray on the machine to join) and its own session
(so that stopping it ends exactly the processes it started, never another Ray's: ``ray stop``
would end every Ray process of the machine). Token authentication is on as Ray's default sets it:
Ray ≥ 2.59's ``ray start --head`` turns it on when a token exists in ``~/.ray/auth_token``, made
here by ``ray get-auth-token --generate`` in a temporary home.
"""

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from himit_torch.runs.sweep import run_sweep

from .test_sweep import (
    child_env,
    read,
    session_processes,
    sigint_as_python_sets_it,
    stop_session,
    wait_until,
    write_spec,
)

pytestmark = [
    pytest.mark.slow,  # a cluster starts in 10–60 s on the 2-core machine
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="finds processes in /proc"),
]

#: Ray's own environment variables that would change what these tests ask (the caller's cluster,
#: token or mode): the tests set their own.
_RAY_VARIABLES = ("RAY_ADDRESS", "RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH")


@dataclass(frozen=True)
class Cluster:
    address: str
    home: Path  # holds .ray/auth_token, the cluster's token
    session: int  # the session of every process the cluster runs


def free_ports(n: int) -> list[int]:
    sockets = [socket.socket() for _ in range(n)]
    try:
        for s in sockets:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def cluster_env(home: Path, **extra: str) -> dict:
    env = {k: v for k, v in child_env().items() if k not in _RAY_VARIABLES}
    return {**env, "HOME": str(home), "RAY_USAGE_STATS_ENABLED": "0", **extra}


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    pytest.importorskip("ray")
    ray = Path(sys.executable).with_name("ray")
    if not ray.exists():
        pytest.skip("no `ray` command beside this Python")
    home = tmp_path_factory.mktemp("home")
    env = cluster_env(home)
    subprocess.run(
        [ray, "get-auth-token", "--generate"], env=env, check=True, capture_output=True, timeout=120
    )
    assert (home / ".ray" / "auth_token").read_text().strip()
    # a short path: Ray's socket files live under it, and a Unix socket's path has ≤ 107 bytes
    temp_dir = Path(tempfile.mkdtemp(prefix="himit-ray-", dir="/tmp"))
    port, client, dashboard, agent = free_ports(4)
    head = subprocess.Popen(
        [
            ray,
            "start",
            "--head",
            "--node-ip-address=127.0.0.1",
            f"--port={port}",
            "--num-cpus=2",
            "--include-dashboard=false",
            f"--temp-dir={temp_dir}",
            # Ray's fixed default ports, which another Ray on the machine may hold
            f"--ray-client-server-port={client}",
            f"--dashboard-port={dashboard}",
            f"--dashboard-agent-listen-port={agent}",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # the session every process of the cluster keeps
    )
    try:
        out, _ = head.communicate(timeout=240)
        assert head.returncode == 0, out
        address = f"127.0.0.1:{port}"
        from himit_torch.runs.ray_cluster import _ask

        # the premise: this cluster refuses a driver that sends no token
        assert _ask(address, None) == "unauthenticated", out
        yield Cluster(address, home, head.pid)
    finally:
        if head.poll() is None:
            head.kill()
        stop_session(head.pid)
        leftover = session_processes(head.pid)
        shutil.rmtree(temp_dir, ignore_errors=True)
        assert not leftover, f"the cluster's processes {leftover} outlived it"


def sweep(spec: Path, out: Path, cluster: Cluster, *flags: str, home: Path | None = None, **env):
    """``himit sweep SPEC --out OUT --address …`` as a user types it, started (not waited for)."""
    return subprocess.Popen(
        [sys.executable, "-m", "himit_torch.cli", "sweep", str(spec), "--out", str(out)]
        + ["--address", cluster.address, *flags],
        env=cluster_env(home or cluster.home, **env),
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=sigint_as_python_sets_it,
    )


def trial_workers(cluster: Cluster) -> dict[int, int]:
    """The cluster's workers running a trial now: process id → niceness."""
    found = {}
    for pid in session_processes(cluster.session):
        try:
            if Path(f"/proc/{pid}/cmdline").read_bytes().startswith(b"ray::run_trial"):
                found[pid] = os.getpriority(os.PRIO_PROCESS, pid)
        except (OSError, ProcessLookupError):
            pass
    return found


def test_a_sweep_on_the_cluster_sends_its_token_and_equals_the_in_process_one(cluster, tmp_path):
    spec = write_spec(tmp_path, grid="")  # one cell, two trials of the compiled engine
    child = sweep(spec, tmp_path / "cluster", cluster, "--worker-niceness", "5")
    niceness: set[int] = set()
    deadline = time.monotonic() + 600
    while child.poll() is None and time.monotonic() < deadline:
        niceness.update(trial_workers(cluster).values())
        time.sleep(0.02)
    if child.poll() is None:
        child.kill()
    _, err = child.communicate()
    assert child.returncode == 0, err
    assert f"({cluster.address}, token from {cluster.home / '.ray' / 'auth_token'}" in err
    assert "InvalidAuthToken" not in err
    # the workers ran at the niceness asked (Ray's own default would be 15)
    assert niceness == {5}, niceness
    run_sweep(spec, tmp_path / "here", use_ray=False, log=lambda line: None)
    for table in ("results.csv", "runs.csv", "summary.csv"):
        assert read(tmp_path / "cluster" / table) == read(tmp_path / "here" / table)


@pytest.mark.parametrize(
    "token, message",
    [
        (None, "wants a token (token authentication) and none is set here"),
        ("not-the-token", "refuses the token from RAY_AUTH_TOKEN"),
    ],
)
def test_a_missing_or_wrong_token_is_one_line_at_once(cluster, tmp_path, token, message):
    empty_home = tmp_path / "home"
    empty_home.mkdir()
    extra = {"RAY_AUTH_TOKEN": token} if token else {}
    child = sweep(write_spec(tmp_path), tmp_path / "out", cluster, home=empty_home, **extra)
    assert child.stderr is not None
    with child.stderr:
        lines = [(time.monotonic(), line.rstrip("\n")) for line in child.stderr]  # as they come
    assert child.wait(timeout=120) == 2, lines
    err = [line for _, line in lines]
    errors = [line for line in err if "error" in line.lower()]
    assert len(errors) == 1 and errors[0] == err[-1], err
    assert errors[0].startswith(f"himit: error: the Ray cluster at {cluster.address} {message}")
    for what_to_set in ("ray get-auth-token", "~/.ray/auth_token", "RAY_AUTH_TOKEN"):
        assert what_to_set in errors[0]
    assert not any("InvalidAuthToken" in line or "Traceback" in line for line in err)
    # from the sweep's first line (its plan) to the error: importing Ray, one request, no
    # more; Ray's own connect would retry for about 20 s
    seconds = lines[-1][0] - lines[0][0]
    print(f"the error came {seconds:.2f} s after the sweep's first line")
    assert err[0].startswith("himit sweep ") and seconds < 10, lines
    assert not (tmp_path / "out" / "trials").exists()


def test_ctrl_c_cancels_the_trials_on_the_cluster_and_a_rerun_resumes_them(cluster, tmp_path):
    # the torch engine: slow enough per window to be interrupted inside a trial
    spec = write_spec(tmp_path, steps=3000, engine="torch", grid="")
    whole = subprocess.Popen(
        [sys.executable, "-m", "himit_torch.cli", "sweep", str(spec), "--no-ray"]
        + ["--out", str(tmp_path / "whole")],
        env=child_env(),
        stderr=subprocess.DEVNULL,
    )
    out = tmp_path / "interrupted"
    trials = out / "trials" / "baseline"
    child = sweep(spec, out, cluster)
    half_way = lambda: any(  # noqa: E731
        (d / "checkpoints" / "world16.pt").exists() and not (d / "results.md").exists()
        for d in (trials.glob("world16_*") if trials.exists() else [])
    )
    wait_until(lambda: child.poll() is not None or half_way(), 300)
    assert child.poll() is None, "the sweep finished before it could be interrupted; lengthen it"
    assert trial_workers(cluster), "no trial running on the cluster"
    signalled = time.monotonic()
    child.send_signal(signal.SIGINT)  # Ctrl-C
    _, err = child.communicate(timeout=60)
    seconds = time.monotonic() - signalled
    assert child.returncode == 130 and seconds < 15, (child.returncode, seconds, err)
    assert err.strip().splitlines()[-1].startswith("himit: error: interrupted:")
    # the trials' tasks are cancelled: their workers end, nothing writes to the trials after
    assert wait_until(lambda: not trial_workers(cluster), 10), trial_workers(cluster)
    stamps = {p: p.stat().st_mtime_ns for p in trials.rglob("*") if p.is_file()}
    time.sleep(3)
    assert {p: p.stat().st_mtime_ns for p in trials.rglob("*") if p.is_file()} == stamps
    finished = sum((d / "results.md").exists() for d in trials.glob("world16_*"))
    started = sum((d / "config.json").exists() for d in trials.glob("world16_*")) - finished
    assert started >= 1 and not (out / "results.csv").exists()
    rerun = sweep(spec, out, cluster)
    _, err = rerun.communicate(timeout=600)
    assert rerun.returncode == 0, err
    assert f"{finished} finished, {started} to resume, {2 - finished - started} new" in err
    assert whole.wait(timeout=600) == 0
    for table in ("results.csv", "runs.csv", "summary.csv"):
        assert read(out / table) == read(tmp_path / "whole" / table)
