"""What the OpenAPI document says beyond FastAPI's own: this server's policy and limits.

FastAPI describes the handlers' types; a client generator or a fuzzer also needs what the
server holds requests to at run time. Each server serves the document of its settings:
- the bearer token where this server asks for it (no ``{}`` alternative): on creating and
  deleting when ``SCENGEN_API_TOKEN`` is set, on every operation but ``PUBLIC`` with
  ``SCENGEN_PROTECT_READS`` too, nowhere without a token (there is nothing to send);
- its largest budget (``SCENGEN_MAX_BUDGET``) as the budgets' maximum;
- its installed controllers as the controller names' enum (a campaign's without the
  certificates, which an ego-only start has not);
- a body that takes a test-case inline or by id as one of two schemas, each with its one
  required base (a generator makes them two types; "neither" and "both" are refused);
- files as what they are: an upload's ``file`` and every body that is not JSON are binary
  strings (text bodies are strings), so that a generated client sends and keeps bytes.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from service.api.media import BINARY
from service.core.sim.controllers import controller_names
from service.settings import Settings

PUBLIC = frozenset({"get_health"})  # answers without the token whatever the settings
BEARER = "HTTPBearer"
BUDGETS = ("budget", "budget_per_level")
ANY_OBJECT = {"type": "object", "additionalProperties": True}
ONE_BASE = ("ExtendRequest", "EvaluationCreate")  # testcase (inline) or testcase_id


def tighten(schema: dict[str, Any], settings: Settings) -> None:
    """Adds this server's policy and limits to FastAPI's document, in place."""
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    for model in components.values():
        _binary_files(model)
        _budget_limits(model, settings.max_budget)
    _controller_choices(schema, components, controller_names())
    _batch_rules(components)
    for body in ONE_BASE:
        if body in components:
            _one_base_of(components, body)
    for operation in _operations(schema):
        _security(operation, settings)
        for code, response in operation.get("responses", {}).items():
            if code.startswith("2"):
                _body_schemas(response)


def _operations(schema: dict[str, Any]) -> Iterator[dict[str, Any]]:
    for operations in schema["paths"].values():
        yield from operations.values()


def _security(operation: dict[str, Any], settings: Settings) -> None:
    if not settings.api_token:
        operation.pop("security", None)
    elif settings.protect_reads and operation.get("operationId") not in PUBLIC:
        operation["security"] = [{BEARER: []}]


def _binary_files(model: dict[str, Any]) -> None:
    """FastAPI declares an UploadFile as ``contentMediaType``, which generators read as
    text to send; ``format: binary`` is what they send as a file."""
    for prop in model.get("properties", {}).values():
        if prop.get("type") == "string" and "contentMediaType" in prop:
            del prop["contentMediaType"]
            prop["format"] = "binary"


def _budget_limits(model: dict[str, Any], limit: float) -> None:
    """A budget over the server's limit is a 422: the schema says so."""
    for name in BUDGETS:
        prop = model.get("properties", {}).get(name)
        if prop is None:
            continue
        for branch in prop.get("anyOf", [prop]):
            if branch.get("type") == "number":
                branch["maximum"] = limit


def _controller_choices(
    schema: dict[str, Any], components: dict[str, Any], names: list[str]
) -> None:
    """Only installed controllers are taken (a client never names a module to import)."""
    choice = {"type": "string", "enum": names}
    if "EvaluationCreate" in components:
        components["EvaluationCreate"]["properties"]["controller"].update(choice)
    if "EvaluateItem" in components:
        components["EvaluateItem"]["properties"]["controllers"]["items"] = dict(choice)
    if "CampaignItem" in components:  # a campaign starts ego-only: nothing to replay
        drivers = [name for name in names if not name.startswith("certificate:")]
        components["CampaignItem"]["properties"]["controllers"]["items"] = {
            "type": "string",
            "enum": drivers,
        }
    for operation in _operations(schema):
        for parameter in operation.get("parameters", []):
            if parameter["name"] == "controller" and parameter["in"] == "query":
                parameter["schema"] = {**choice, "title": "Controller"}


def _body_schemas(response: dict[str, Any]) -> None:
    """Every body has a schema: JSON an object where FastAPI left it open, text a string,
    anything else (zip, XML, PNG, SVG) a binary string."""
    for media, entry in response.get("content", {}).items():
        given = entry.get("schema") or {}
        if media == "application/json" or media.endswith("+json"):
            entry["schema"] = given or dict(ANY_OBJECT)
        elif media.startswith("text/"):
            entry["schema"] = given or {"type": "string"}
        elif given in ({}, {"type": "string"}):
            entry["schema"] = dict(BINARY)


def _one_base_of(components: dict[str, Any], name: str) -> None:
    """``name`` becomes one of ``<name>Inline`` (``testcase`` required) and ``<name>ById``
    (``testcase_id`` required): exactly one, never null, as the model's validators hold."""
    model = components[name]
    variants = []
    for suffix, base, other in (
        ("Inline", "testcase", "testcase_id"),
        ("ById", "testcase_id", "testcase"),
    ):
        properties = {key: dict(value) for key, value in model["properties"].items()}
        del properties[other]
        given = properties[base]
        properties[base] = {
            **next(b for b in given["anyOf"] if b.get("type") != "null"),
            "description": given.get("description", ""),
        }
        components[f"{name}{suffix}"] = {
            **model,
            "title": f"{name}{suffix}",
            "properties": properties,
            "required": sorted({*model.get("required", []), base}),
        }
        variants.append({"$ref": f"#/components/schemas/{name}{suffix}"})
    components[name] = {"title": name, "description": model["description"], "oneOf": variants}


RULES_ACROSS_FIELDS = {  # what the models check that JSON Schema cannot say: in words
    "Params": "v_stop < v_run < v_max.",
    "ExtendItem": "Exactly one of testcase_id, testcase and after; at least one new road "
    "user (routes and pedestrians), six at most.",
    "ChainItem": "Exactly one of testcase_id, testcase and after; of steps and levels.",
    "EvaluateItem": "Exactly one of testcase_id, testcase and items.",
    "CampaignItem": "Exactly one of egos and all_egos: true.",
    "Batch": "An item refers only to earlier items, and only to those that make test-cases.",
}


def _batch_rules(components: dict[str, Any]) -> None:
    """What the batch's items hold a list to (a campaign's egos each once, a chain's steps
    each with a route), and the rules across fields in the models' descriptions."""
    for name, rule in RULES_ACROSS_FIELDS.items():
        if name in components:
            described = components[name].get("description", "").rstrip()
            components[name]["description"] = f"{described} {rule}".strip()
    if "CampaignItem" in components:
        egos = components["CampaignItem"]["properties"]["egos"]["anyOf"][0]
        egos["uniqueItems"] = True
    if "ChainItem" in components:
        steps = components["ChainItem"]["properties"]["steps"]["anyOf"][0]
        steps["items"]["minItems"] = 1
