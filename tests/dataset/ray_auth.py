"""Ray's token authentication state, reset after the tests change its environment (Ray reads it once, on import)."""

from __future__ import annotations

try:
    from ray._private.authentication_test_utils import reset_auth_token_state  # what Ray's own tests use
except ImportError:  # an older Ray, without token authentication

    def reset_auth_token_state() -> None:
        pass


__all__ = ["reset_auth_token_state"]
