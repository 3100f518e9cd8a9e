"""Robot tokens: random secrets shown once, stored and looked up by their SHA-256."""

from __future__ import annotations

import hashlib
import secrets

TOKEN_PREFIX = "cnr_"


def new_token() -> str:
    """Return a fresh token with 256 bits of randomness."""
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def token_digest(token: str) -> str:
    """Return the hex SHA-256 under which ``token`` is stored.

    A plain hash is enough: tokens are random and long, so there is nothing to brute-force,
    and a lookup by digest is one indexed query.
    """
    return hashlib.sha256(token.encode("utf-8")).hexdigest()
