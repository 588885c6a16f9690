"""The committed OpenAPI document: ``python -m service.api.openapi [FILE]`` (``make openapi``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from service.api.app import create_app
from service.settings import Settings

COMMITTED = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"
# The committed document is that of a server with a token (writes need it), public reads,
# and the default limits, whatever this machine's SCENGEN_* variables say; each server
# serves its own at /openapi.json.
COMMITTED_SETTINGS = Settings(
    api_token="a token is set",
    protect_reads=False,
    max_budget=Settings.model_fields["max_budget"].default,
)


def openapi_document() -> str:
    """The app's OpenAPI document, formatted for clean diffs."""
    schema = create_app(COMMITTED_SETTINGS).openapi()
    return json.dumps(schema, indent=2, ensure_ascii=False) + "\n"


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else COMMITTED
    target.write_text(openapi_document())
    print(f"wrote {target}", file=sys.stderr)
