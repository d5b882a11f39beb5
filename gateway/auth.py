"""Who may talk to the gateway: shared secrets, a per-connection HMAC challenge-response, roles, optional TLS.

Why this shape (issue 13 "two machines", issue 12 "security"):

* **Challenge-response, not a password on the wire.** The server's hello carries a fresh 32-byte nonce; the
  client answers with its own nonce and ``HMAC-SHA256(secret, "courtside-auth-v1|client|" + both nonces)``. The
  server answers with the same MAC under the label ``server``, so the client also knows it reached a gateway that
  holds the secret. A captured exchange cannot be replayed (the server's nonce is new each time) and never
  reveals the secret. Without TLS the stream after the handshake is not encrypted: use TLS on untrusted networks.
* **The secret decides the role.** An operator secret (record, station commands, calibration) and optionally a
  second, viewer secret (stream and status only). The server tries both, so a client needs only its one file.
* **The server checks the role of every request** (`required_role`); clients are never trusted to limit
  themselves.
* **Without a secret the gateway listens on loopback only** (`gateway.court_config.check_consistent`) and every
  local client is an operator, as before. On a machine shared with untrusted users, configure a secret: then
  every client, local ones included, authenticates.
* Secrets are read from files (never the command line, where ``ps`` shows them); a secret file readable by
  group or others is refused, as ssh refuses such keys.
"""
from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import ssl
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from engine.errors import CourtsideError, MalformedFileError

OPERATOR = "operator"
VIEWER = "viewer"
ROLES = (VIEWER, OPERATOR)
NONCE_BYTES = 32
MIN_SECRET_BYTES = 16
SECRET_FILE_ENV = "COURTSIDE_SECRET_FILE"  # path of the client's secret file
SECRET_ENV = "COURTSIDE_SECRET"  # or the secret itself (for service managers that inject secrets)
_LABEL = b"courtside-auth-v1|"

# Requests a viewer may make: they change nothing. Everything else needs an operator.
VIEWER_ACTIONS = frozenset({"ping", "list_stations", "status"})
VIEWER_CALIBRATION_ACTIONS = frozenset({"state"})


class AuthenticationError(CourtsideError, ConnectionError):
    """The gateway and a client could not agree on who the client is (wrong or missing secret)."""


def required_role(action: str, args: dict[str, Any]) -> str:
    """The role a request needs: viewers may only read."""
    if action in VIEWER_ACTIONS:
        return VIEWER
    if action == "calibration" and args.get("action") in VIEWER_CALIBRATION_ACTIONS:
        return VIEWER
    return OPERATOR


def permits(role: str, needed: str) -> bool:
    return ROLES.index(role) >= ROLES.index(needed)


def new_secret() -> str:
    """A fresh secret (64 hex characters = 256 bits) for `write_secret_file`."""
    return secrets.token_hex(32)


def write_secret_file(path: str | Path) -> Path:
    """Create ``path`` with a new secret, readable by its owner only (refuses to overwrite)."""
    path = Path(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write(new_secret() + "\n")
    return path


def _check_secret(secret: bytes, where: str | Path) -> bytes:
    secret = secret.strip()
    if len(secret) < MIN_SECRET_BYTES:
        raise MalformedFileError(where, None, f"secret is {len(secret)} bytes; use at least {MIN_SECRET_BYTES} "
                                 "(e.g. `courtside gateway new-secret FILE`)")
    return secret


def read_secret_file(path: str | Path) -> bytes:
    """The secret in ``path`` (surrounding whitespace stripped). Refused when group/others may read it."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
        data = path.read_bytes()
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read secret file: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise MalformedFileError(path, None, "secret file is not a regular file")
    if mode & 0o077:
        raise MalformedFileError(path, None, f"secret file is readable by others (mode {stat.S_IMODE(mode):o}); "
                                 f"run: chmod 600 {path}")
    return _check_secret(data, path)


def client_secret(secret_file: str | Path | None = None, environ: dict[str, str] | None = None) -> bytes | None:
    """The secret a client uses: ``secret_file`` if given, else ``$COURTSIDE_SECRET_FILE``, else
    ``$COURTSIDE_SECRET``; None when none is set (fine for a loopback gateway without authentication)."""
    env = os.environ if environ is None else environ
    if secret_file is not None:
        return read_secret_file(secret_file)
    if env.get(SECRET_FILE_ENV):
        return read_secret_file(env[SECRET_FILE_ENV])
    if env.get(SECRET_ENV):
        return _check_secret(env[SECRET_ENV].encode(), f"${SECRET_ENV}")
    return None


def proof(secret: bytes, side: str, server_nonce: bytes, client_nonce: bytes) -> str:
    """``HMAC-SHA256(secret, label | side | server_nonce | client_nonce)`` as hex; ``side`` is client/server."""
    message = _LABEL + side.encode() + b"|" + server_nonce + client_nonce
    return hmac.new(secret, message, hashlib.sha256).hexdigest()


@dataclass(frozen=True)
class Secrets:
    """The server's secrets. ``operator`` None = no authentication (loopback only, everyone is an operator)."""

    operator: bytes | None = None
    viewer: bytes | None = None

    def __post_init__(self) -> None:
        if self.viewer is not None and self.operator is None:
            raise CourtsideError("a viewer secret needs an operator secret too")
        if self.viewer is not None and hmac.compare_digest(self.viewer, self.operator or b""):
            raise CourtsideError("the viewer and operator secrets are the same; a viewer would be an operator")

    @property
    def required(self) -> bool:
        return self.operator is not None

    @classmethod
    def from_files(cls, operator_file: Path | None, viewer_file: Path | None) -> "Secrets":
        """Read both files; two files holding one secret are refused naming both (issue 22)."""
        operator = read_secret_file(operator_file) if operator_file else None
        viewer = read_secret_file(viewer_file) if viewer_file else None
        if viewer is not None and operator is not None and hmac.compare_digest(viewer, operator):
            raise MalformedFileError(viewer_file, None, f"viewer_secret_file holds the same secret as "
                                     f"operator_secret_file {operator_file}: a viewer would be an operator")
        return cls(operator, viewer)

    def verify(self, client_proof: object, server_nonce: bytes, client_nonce: bytes) -> tuple[str, bytes] | None:
        """(role, secret) whose client proof matches, else None. Both are always computed (no early exit that
        would tell a timing observer which secret was tried)."""
        if not isinstance(client_proof, str) or not client_proof.isascii():
            return None  # compare_digest raises TypeError on non-ASCII text (issue 22)
        found = None
        for role, secret in ((OPERATOR, self.operator), (VIEWER, self.viewer)):
            if secret is not None and hmac.compare_digest(proof(secret, "client", server_nonce, client_nonce),
                                                          client_proof) and found is None:
                found = (role, secret)
        return found


def server_tls_context(cert: Path, key: Path) -> ssl.SSLContext:
    """TLS 1.2+ server context from PEM files; errors name the file."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_cert_chain(cert, key)
    except (OSError, ssl.SSLError) as exc:
        raise MalformedFileError(cert, None, f"cannot load TLS certificate/key ({key}): {exc}") from None
    return context


def client_tls_context(ca_file: str | Path | None = None) -> ssl.SSLContext:
    """TLS client context verifying the gateway against ``ca_file`` (e.g. the gateway's self-signed
    certificate) or the system CAs. Host names are not checked when a CA file pins the certificate, because a
    court board is usually reached by IP address."""
    context = ssl.create_default_context(cafile=str(ca_file) if ca_file else None)
    if ca_file:
        context.check_hostname = False
    return context
