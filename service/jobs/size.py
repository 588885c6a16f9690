"""A batch's size: the steps its items run at most, counted as they would run them, so
that a job too big for the server (``SCENGEN_MAX_JOB_STEPS``) is refused when it is
submitted rather than holding the workers for days.

A step is one extension (an extend item's ``count``, a chain's levels), one evaluation
(an evaluate item's controllers times the test-cases it judges), or a campaign's step as
its progress counts them (``CampaignPlan.steps``: per ego route its controllers on the
ego-only start, then per chain and level the level grown and its verdicts). Every count is
an upper bound: a chain that stops early, or ego routes an ``all_egos`` campaign leaves out
(a signal that stays red), run fewer.
"""

from __future__ import annotations

from collections.abc import Callable

from service.core.campaign.outcome import CampaignPlan
from service.core.errors import InvalidInput
from service.jobs.batch import AnyItem, Batch, CampaignItem, ChainItem, EvaluateItem, ExtendItem

EgoCount = Callable[[CampaignItem], int]  # an all_egos campaign's ego routes, at most


def item_sizes(batch: Batch, egos_of: EgoCount) -> list[tuple[int, int]]:
    """For each item, (steps it runs, test-cases it makes) at most."""
    sizes: list[tuple[int, int]] = []
    for item in batch.items:
        sizes.append(_size(item, sizes, egos_of))
    return sizes


def job_steps(batch: Batch, egos_of: EgoCount) -> int:
    """The steps ``batch`` runs at most."""
    return sum(steps for steps, _ in item_sizes(batch, egos_of))


def check_job_size(batch: Batch, egos_of: EgoCount, limit: int) -> None:
    """InvalidInput naming the count, the items that make it and ``limit`` when ``batch``
    runs more than ``limit`` steps."""
    sizes = item_sizes(batch, egos_of)
    total = sum(steps for steps, _ in sizes)
    if total <= limit:
        return
    largest = max(range(len(sizes)), key=lambda i: sizes[i][0])
    raise InvalidInput(
        f"the batch runs up to {total:,} steps (extensions, levels and evaluations; "
        f"items[{largest}] {sizes[largest][0]:,} of them), more than this server's limit of "
        f"{limit:,} (SCENGEN_MAX_JOB_STEPS): split it into smaller jobs, or give fewer "
        "chains, levels, egos or controllers"
    )


def _size(item: AnyItem, earlier: list[tuple[int, int]], egos_of: EgoCount) -> tuple[int, int]:
    if isinstance(item, ExtendItem):
        return item.count, item.count
    if isinstance(item, ChainItem):
        return item.count, item.count
    if isinstance(item, EvaluateItem):
        judged = 1 if item.items is None else sum(earlier[i][1] for i in set(item.items))
        return judged * len(item.controllers), 0
    egos = len(item.egos) if item.egos is not None else egos_of(item)
    plan = CampaignPlan(
        network=item.network,
        junction=item.junction or "",
        control="",
        egos=("",) * egos,
        depth=item.depth,
        chains=item.chains,
        controllers=tuple(item.controllers),
    )
    return plan.steps, egos * (1 + item.chains * item.depth)
