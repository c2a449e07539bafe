"""Joining a running Ray cluster: its token authentication, settled before Ray's own connect.

Ray (≥ 2.52) can demand a token on every request (``RAY_AUTH_MODE=token``, "set via the
environment and … configured consistently on every node"). The token is looked up, "highest to
lowest precedence", in ``RAY_AUTH_TOKEN``, the file named by ``RAY_AUTH_TOKEN_PATH``
(unreadable or empty: "a fatal misconfiguration"), then ``~/.ray/auth_token``;
``ray get-auth-token`` prints a node's token
(https://docs.ray.io/en/latest/ray-security/token-auth.html,
https://docs.ray.io/en/master/ray-core/internals/token-authentication.html). Since Ray 2.59
``ray start --head`` turns token authentication on whenever a token exists (any local
``ray.init()`` writes one; ray-project/ray#64755, in 2.59 as #66248), but a driver joining an
explicit address does not (Ray 2.60, ``ray/_private/worker.py``: "Only a local cluster found
automatically auto-enables auth; an explicit address (argument or RAY_ADDRESS) never does"):
``ray.init(address="host:port")`` sends no token, then retries for about 20 s, logging
``InvalidAuthToken`` every second, before "Failed to connect to Ray cluster".

Hence :func:`prepare_to_join` first sends the cluster's GCS one ``GetClusterId`` request without a
token. If it is refused as unauthenticated, the token is looked up as Ray does, checked with a
second request, and ``RAY_AUTH_MODE=token`` set for this process, so that Ray itself sends it.
No token, a refused one or no answer raise at once, with one line saying what to set.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["ClusterAuthError", "PROBE_SECONDS", "find_token", "prepare_to_join"]

#: The GCS method asked (any would do: with token authentication on, every one needs the token).
_PROBE_METHOD = "/ray.rpc.NodeInfoGcsService/GetClusterId"
#: Seconds to wait for a cluster's answer (an answer, even a refusal, takes milliseconds).
PROBE_SECONDS = 10.0
_HOW = (
    "copy the head node's token (`ray get-auth-token` there prints it) into ~/.ray/auth_token, "
    "or set RAY_AUTH_TOKEN (or RAY_AUTH_TOKEN_PATH, a file holding it)"
)


class ClusterAuthError(ValueError):
    """The cluster wants a token this process cannot give (a setting to fix, not a failure to
    retry: ``himit`` ends with exit status 2)."""


def find_token() -> tuple[str, str] | None:
    """The token Ray would send and where it was found, in Ray's documented precedence:
    ``RAY_AUTH_TOKEN``, the file ``RAY_AUTH_TOKEN_PATH``, ``~/.ray/auth_token``; ``None`` if none.

    Raises:
        ClusterAuthError: ``RAY_AUTH_TOKEN_PATH`` names a file that cannot be read or is empty
            (Ray itself would abort on it).
    """
    token = os.environ.get("RAY_AUTH_TOKEN", "").strip()
    if token:
        return token, "RAY_AUTH_TOKEN"
    named = os.environ.get("RAY_AUTH_TOKEN_PATH")
    if named:
        try:
            token = Path(named).expanduser().read_text().strip()
        except (OSError, UnicodeDecodeError) as err:
            raise ClusterAuthError(
                f"RAY_AUTH_TOKEN_PATH={named} cannot be read ({err.__class__.__name__}); "
                "point it at the file holding the cluster's token"
            ) from None
        if not token:
            raise ClusterAuthError(f"RAY_AUTH_TOKEN_PATH={named} is empty; {_HOW}")
        return token, named
    default = Path.home() / ".ray" / "auth_token"
    try:
        token = default.read_text().strip()
    except (OSError, UnicodeDecodeError):
        return None
    return (token, str(default)) if token else None


def _ask(address: str, token: str | None) -> str:
    """``"ok"``, ``"unauthenticated"`` or ``"unreachable: <why>"``: the GCS at ``address``
    asked once, with the token in the ``authorization: Bearer`` header if one is given."""
    import grpc  # Ray's own dependency

    metadata = (("authorization", f"Bearer {token}"),) if token else ()
    with grpc.insecure_channel(address) as channel:
        call = channel.unary_unary(
            _PROBE_METHOD,
            request_serializer=lambda request: request,  # GetClusterIdRequest: no fields, b""
            response_deserializer=lambda reply: reply,
        )
        try:
            call(b"", timeout=PROBE_SECONDS, metadata=metadata)
        except grpc.RpcError as err:
            code = err.code() if hasattr(err, "code") else None
            if code == grpc.StatusCode.UNAUTHENTICATED:
                return "unauthenticated"
            if code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED):
                details = err.details() if hasattr(err, "details") else ""
                return f"unreachable: {details or code.name}"
            # another refusal (an older GCS without the method, …): it answered, and Ray's own
            # connect will say what it makes of it
    return "ok"


def prepare_to_join(address: str) -> str:
    """Settle token authentication before ``ray.init(address=address)``; returns a few words
    for the log ("no token asked", "token from ~/.ray/auth_token").

    Only an explicit ``host:port`` is asked: ``"auto"`` is left to Ray, which turns token
    authentication on by itself there when it finds a token, and so is a Ray Client address
    (``ray://…``). ``RAY_AUTH_MODE``, where set, is respected.

    Raises:
        ClusterAuthError: the cluster wants a token and none is found, the one found is refused,
            or ``RAY_AUTH_MODE`` says otherwise; the message says what to set.
        ConnectionError: no Ray cluster answers at ``address`` within :data:`PROBE_SECONDS`.
    """
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit() or "://" in address:
        return "address resolved by Ray"
    mode = os.environ.get("RAY_AUTH_MODE", "").strip().lower()
    found = find_token()
    if mode == "token" and found is None:
        raise ClusterAuthError(f"RAY_AUTH_MODE=token but no Ray token is set: {_HOW}")
    answer = _ask(address, None)
    if answer.startswith("unreachable"):
        raise ConnectionError(
            f"no Ray cluster answers at {address} ({answer.split(': ', 1)[1]}); start one there "
            "with `ray start --head --port=…` (docs/cluster.md), or check the address"
        )
    if answer == "ok":
        return "no token asked"
    if mode == "disabled":
        raise ClusterAuthError(
            f"the Ray cluster at {address} wants a token but RAY_AUTH_MODE=disabled; unset it "
            f"and {_HOW}"
        )
    if found is None:
        raise ClusterAuthError(
            f"the Ray cluster at {address} wants a token (token authentication) and none is "
            f"set here: {_HOW}"
        )
    token, source = found
    if _ask(address, token) == "unauthenticated":
        raise ClusterAuthError(
            f"the Ray cluster at {address} refuses the token from {source} (not this "
            f"cluster's): {_HOW}"
        )
    os.environ["RAY_AUTH_MODE"] = "token"
    if "ray._raylet" in sys.modules:  # Ray caches its config at import: reload it, as Ray's
        # own switch does (ray/_private/authentication/authentication_token_setup.py)
        sys.modules["ray._raylet"].Config.initialize("")
    return f"token from {source}"
