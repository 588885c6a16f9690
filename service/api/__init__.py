"""The HTTP API: FastAPI routes over ``service.core``, errors as problem+json."""

from service.api.app import create_app

__all__ = ["create_app"]
