"""What a batch names that this service does not have (stored test-cases, networks,
installed controllers), found when it is submitted: a job is refused for it at once rather
than accepted and failed later."""

from __future__ import annotations

from service.core.errors import InvalidInput, InvalidTestCase, UnknownNetwork, choices
from service.core.sim.controllers import controller_names
from service.jobs.batch import Batch, CampaignItem, EvaluateItem
from service.store import Store


def check_references(batch: Batch, store: Store) -> None:
    """InvalidInput naming everything ``batch`` names that ``store`` does not have, each
    with where it is named and the valid choices (its ``errors``: one line for each)."""
    found = unknown_references(batch, store)
    if found:
        raise InvalidInput(
            f"the batch names what this server does not have: {'; '.join(found)}",
            errors=found,
        )


def unknown_references(batch: Batch, store: Store) -> list[str]:
    """One line for each unknown test-case id, network and controller ``batch`` names, and
    each inline test-case this server cannot take, in the order of the items."""
    named = {
        item.testcase_id
        for item in batch.items
        if not isinstance(item, CampaignItem) and item.testcase_id is not None
    }
    stored = store.stored_testcases(named)
    installed = controller_names()
    networks: list[str] | None = None  # read once, when a message needs them
    found = []
    for position, item in enumerate(batch.items):
        where = f"items[{position}]"
        if isinstance(item, CampaignItem):
            if store.network(item.network) is None:
                networks = networks or [n.id for n in store.list_networks()]
                found.append(
                    f"{where}.network: no network {item.network!r} (known networks: "
                    f"{choices(networks)})"
                )
        elif item.testcase_id is not None and item.testcase_id not in stored:
            found.append(
                f"{where}.testcase_id: no stored test-case {item.testcase_id!r} (POST "
                "/testcases makes one, GET /testcases lists them)"
            )
        elif item.testcase is not None:
            try:
                store.check_inline(item.testcase)
            except (InvalidTestCase, UnknownNetwork) as error:
                found.append(f"{where}.testcase: {error.message}")
        if isinstance(item, (EvaluateItem, CampaignItem)):
            found += [
                f"{where}.controllers: {name!r} is not a controller installed here (valid "
                f"choices: {choices(installed)})"
                for name in item.controllers
                if name not in installed
            ]
    return found
