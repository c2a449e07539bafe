"""Joining a Ray cluster (``himit_torch.runs.ray_cluster``): the token looked up in Ray's documented
order, and the one request that tells what the cluster wants, against a stand-in GCS that serves
the method asked (a real cluster: ``test_sweep_cluster.py``, slow)."""

import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import pytest

from himit_torch.runs.ray_cluster import ClusterAuthError, find_token, prepare_to_join

grpc = pytest.importorskip("grpc")

_VARIABLES = ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH")


@pytest.fixture
def home(tmp_path, monkeypatch):
    """An empty home and none of Ray's token variables; each restored afterwards, also where the
    code under test sets one."""
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    for name in _VARIABLES:
        monkeypatch.setenv(name, "")  # remembers the caller's value (or its absence) …
        monkeypatch.delenv(name)  # … and starts the test without it
    return home


@pytest.fixture
def ray_config(monkeypatch):
    """Ray's config cache, stood in for: the reloads asked of it."""
    reloads: list[str] = []
    raylet = SimpleNamespace(Config=SimpleNamespace(initialize=reloads.append))
    monkeypatch.setitem(sys.modules, "ray._raylet", raylet)
    return reloads


def gcs(token: str | None):
    """A stand-in GCS on a free loopback port answering GetClusterId, refusing it as Ray does
    (UNAUTHENTICATED) unless the ``authorization`` header carries ``token`` (if one is set)."""

    def get_cluster_id(request, context):
        sent = dict(context.invocation_metadata()).get("authorization")
        if token is not None and sent != f"Bearer {token}":
            context.abort(grpc.StatusCode.UNAUTHENTICATED, "InvalidAuthToken")
        return b""

    server = grpc.server(ThreadPoolExecutor(max_workers=1))
    method = grpc.unary_unary_rpc_method_handler(
        get_cluster_id, request_deserializer=bytes, response_serializer=bytes
    )
    server.add_generic_rpc_handlers(
        (
            grpc.method_handlers_generic_handler(
                "ray.rpc.NodeInfoGcsService", {"GetClusterId": method}
            ),
        )
    )
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    return server, f"127.0.0.1:{port}"


@pytest.fixture
def token_cluster():
    server, address = gcs("the-token")
    yield address
    server.stop(None)


def test_the_token_is_found_in_rays_documented_order(home, monkeypatch, tmp_path):
    assert find_token() is None
    (home / ".ray").mkdir()
    (home / ".ray" / "auth_token").write_text("from-home\n")
    assert find_token() == ("from-home", str(home / ".ray" / "auth_token"))
    named = tmp_path / "token.txt"
    named.write_text("from-path")
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(named))
    assert find_token() == ("from-path", str(named))
    monkeypatch.setenv("RAY_AUTH_TOKEN", "from-env")
    assert find_token() == ("from-env", "RAY_AUTH_TOKEN")
    # a path that names nothing readable is an error (Ray aborts on it), not a fall-back
    monkeypatch.delenv("RAY_AUTH_TOKEN")
    named.write_text("")
    with pytest.raises(ClusterAuthError, match="RAY_AUTH_TOKEN_PATH=.* is empty"):
        find_token()
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "missing"))
    with pytest.raises(ClusterAuthError, match="cannot be read"):
        find_token()


def test_a_cluster_without_authentication_is_joined_as_it_is(home, ray_config):
    server, address = gcs(None)
    try:
        assert prepare_to_join(address) == "no token asked"
    finally:
        server.stop(None)
    assert "RAY_AUTH_MODE" not in os.environ and ray_config == []


def test_the_token_a_cluster_wants_is_found_and_turned_on(home, ray_config, token_cluster):
    (home / ".ray").mkdir()
    (home / ".ray" / "auth_token").write_text("the-token")
    assert prepare_to_join(token_cluster) == f"token from {home / '.ray' / 'auth_token'}"
    # Ray then sends it itself: token mode on, its cached config reloaded to see it
    assert os.environ["RAY_AUTH_MODE"] == "token" and ray_config == [""]


@pytest.mark.parametrize(
    "variables, message",
    [
        ({}, "wants a token \\(token authentication\\) and none is set here: copy the head"),
        ({"RAY_AUTH_TOKEN": "stale"}, "refuses the token from RAY_AUTH_TOKEN \\(not this"),
        ({"RAY_AUTH_TOKEN": "the-token", "RAY_AUTH_MODE": "disabled"}, "RAY_AUTH_MODE=disabled"),
        ({"RAY_AUTH_MODE": "token"}, "RAY_AUTH_MODE=token but no Ray token is set"),
    ],
)
def test_a_token_that_cannot_be_sent_is_named_at_once(
    home, ray_config, token_cluster, monkeypatch, variables, message
):
    for name, value in variables.items():
        monkeypatch.setenv(name, value)
    started = time.monotonic()
    with pytest.raises(ClusterAuthError, match=message) as error:
        prepare_to_join(token_cluster)
    assert time.monotonic() - started < 2
    assert "\n" not in str(error.value) and ray_config == []
    assert isinstance(error.value, ValueError)  # himit: exit status 2


def test_nothing_answering_is_a_connection_error_at_once(home):
    server, address = gcs(None)
    server.stop(None)  # the port, now closed
    started = time.monotonic()
    with pytest.raises(ConnectionError, match=f"no Ray cluster answers at {address}"):
        prepare_to_join(address)
    assert time.monotonic() - started < 5


def test_addresses_ray_resolves_itself_are_left_to_it(home, ray_config):
    for address in ("auto", "ray://head:10001"):
        assert prepare_to_join(address) == "address resolved by Ray"
    assert ray_config == []
