"""The committed OpenAPI document: ``python -m service.api.openapi [FILE]`` (``make openapi``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from service.api.app import create_app
from service.settings import Settings

COMMITTED = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"


def openapi_document() -> str:
    """The app's OpenAPI document, formatted for clean diffs."""
    schema = create_app(Settings()).openapi()
    return json.dumps(schema, indent=2, ensure_ascii=False) + "\n"


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else COMMITTED
    target.write_text(openapi_document())
    print(f"wrote {target}", file=sys.stderr)
