"""The batch the job tests run: fast, with every kind of item."""

from __future__ import annotations

from typing import Any

from service.api.schemas import example_testcase


def regression_batch() -> dict[str, Any]:
    """Extend the four-way example once; grow it by two levels; judge both results with two
    controllers: 3 test-cases, 6 evaluations."""
    root = example_testcase()
    return {
        "name": "four-way regression",
        "items": [
            {"kind": "extend", "testcase": root, "routes": ["S2C_1:C2N_1"], "seed": 0},
            {"kind": "chain", "testcase": root, "steps": [["S2C_1:C2N_1"], ["W2C_1:C2E_1"]],
             "seed": 1},
            {"kind": "evaluate", "items": [0, 1],
             "controllers": ["sumo", "certificate:solvability"]},
        ],
    }  # fmt: skip


def results(job: dict[str, Any], client: Any) -> dict[str, Any]:
    """What a job made, independent of where it ran: test-case ids per item, and each
    evaluation's verdict by (test-case, controller)."""
    verdicts = {}
    for item in job["items"]:
        for ident in item["evaluations"]:
            evaluation = client.get(f"/evaluations/{ident}").json()
            verdicts[(evaluation["testcase"], evaluation["controller"])] = evaluation["passed"]
    return {"testcases": [item["testcases"] for item in job["items"]], "verdicts": verdicts}
