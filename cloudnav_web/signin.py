"""HTTP Basic on the API, answering 429 while its sign-in is locked out.

django-axes (settings) counts every failed sign-in and refuses a locked-out one, but DRF
reports that refusal as any wrong password (401); this says what it is, as the login page
does, so a client backs off instead of asking for another password.
"""

from __future__ import annotations

from typing import Any

from rest_framework import authentication, exceptions
from rest_framework.request import Request


class RateLimitedBasicAuthentication(authentication.BasicAuthentication):
    def authenticate_credentials(
        self, userid: str, password: str, request: Request | None = None
    ) -> tuple[Any, None]:
        try:
            return super().authenticate_credentials(userid, password, request)
        except exceptions.AuthenticationFailed:
            if getattr(request, "axes_locked_out", False):
                raise exceptions.Throttled(
                    detail="Too many failed sign-ins; try again later."
                ) from None
            raise
