"""A batch's size in steps (service.jobs.size), counted as its items run them."""

from __future__ import annotations

import pytest

from service.core.errors import InvalidInput
from service.jobs.batch import parse_batch
from service.jobs.size import check_job_size, item_sizes, job_steps
from tests.jobs.batches import regression_batch

CAMPAIGN = {"kind": "campaign", "network": "4way-signal", "all_egos": True, "depth": 10,
            "chains": 100, "controllers": ["sumo"] * 8}  # fmt: skip


def test_every_kind_of_item_is_counted() -> None:
    """An extension and a chain of two levels make 3 test-cases, judged by 2 controllers:
    3 extensions and 6 evaluations."""
    batch = parse_batch(regression_batch())
    assert item_sizes(batch, lambda item: 1) == [(1, 1), (2, 2), (6, 0)]
    assert job_steps(batch, lambda item: 1) == 9


def test_a_campaign_counts_as_its_progress_does() -> None:
    """Per ego: the ego-only start judged by 8 controllers, then 100 chains of 10 levels,
    each grown and judged by 8: the 144,128 steps of issue 50 over 16 ego routes."""
    batch = parse_batch({"items": [CAMPAIGN]})
    assert job_steps(batch, lambda item: 16) == 16 * (8 + 100 * 10 * 9) == 144_128
    with pytest.raises(InvalidInput) as refused:
        check_job_size(batch, lambda item: 16, 2000)
    assert "144,128 steps" in refused.value.message and "limit of 2,000" in str(refused.value)
    check_job_size(batch, lambda item: 16, 144_128)  # at the limit: taken
