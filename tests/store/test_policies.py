"""Policies in the store, on SQLite and PostgreSQL: a sent table is kept exactly, listed per
owner a page at a time, read by the name a scenario gives it, and deleted for good."""

from __future__ import annotations

import numpy as np
import pytest

from nanonav.engine import qlearning
from nanonav.store import (
    Idempotency,
    IdempotencyKeyReused,
    JobStore,
    PolicyNotFound,
    policy_name,
    policy_number,
)
from nanonav.store.errors import PolicyInUse, PolicyLimitReached


def add(store: JobStore, owner: str = "", robots: int | None = None, fill: float = 0.25) -> int:
    states, actions = qlearning.labels("steering", "broadcast")
    shape = (len(states), len(actions)) if robots is None else (robots, len(states), len(actions))
    values = np.full(shape, fill)
    values[..., 0, 1] = -3.5
    record = store.policies.add(
        action_set="steering",
        communication=("broadcast",),
        states=states,
        actions=actions,
        values=values,
        name=f"filled with {fill}",
        owner=owner,
    )
    return record.id


def test_a_policy_keeps_its_labels_and_values_exactly(store: JobStore) -> None:
    policy_id = add(store, owner="a" * 64, robots=3, fill=1 / 3)
    record = store.policies.get(policy_id)
    assert (record.action_set, record.communication) == ("steering", ("broadcast",))
    assert (record.states, record.actions, record.tables, record.per_robot) == (64, 5, 3, True)
    assert record.policy_from == f"policy-{policy_id}" and record.owner == "a" * 64
    assert record.name == "filled with 0.3333333333333333"
    table = store.policies.table(policy_id)
    states, actions = qlearning.labels("steering", "broadcast")
    assert table["states"].tolist() == states and table["actions"].tolist() == actions
    assert table["values"].shape == (3, 64, 5) and table["values"].dtype == np.float64
    assert table["values"][2, 0, 1] == -3.5 and table["values"][1, 5, 4] == 1 / 3
    shared = store.policies.get(add(store))
    assert (shared.tables, shared.per_robot) == (1, False)


def test_the_job_store_reads_a_policy_by_the_name_a_scenario_gives_it(store: JobStore) -> None:
    policy_id = add(store, owner="b" * 64)
    name = policy_name(policy_id)
    assert policy_number(name) == policy_id
    assert store.owner_of(name) == "b" * 64
    assert np.array_equal(store.qtable(name)["values"], store.policies.table(policy_id)["values"])
    job = store.enqueue({}, robot_steps=1, episodes=1, owner="c" * 64)
    assert store.owner_of(job.id) == "c" * 64  # a job's id still names the job
    assert store.owner_of(policy_name(policy_id + 1)) is None
    with pytest.raises(PolicyNotFound, match=f"^there is no policy {policy_id + 1}$"):
        store.qtable(policy_name(policy_id + 1))
    for name in ("job-3", "policy-01", "policy-\u0661", "policy-\u00b2"):
        with pytest.raises(ValueError, match="not a policy's name"):
            policy_number(name)


def test_policies_are_listed_newest_first_per_owner_a_page_at_a_time(store: JobStore) -> None:
    mine = [add(store, owner="m" * 64) for _ in range(3)]
    theirs = add(store, owner="t" * 64)
    first = store.policies.page(limit=2, before_id=None, owner="m" * 64)
    assert [p.id for p in first.policies] == [mine[2], mine[1]]
    assert first.next_before_id == mine[1]
    rest = store.policies.page(limit=2, before_id=first.next_before_id, owner="m" * 64)
    assert [p.id for p in rest.policies] == [mine[0]] and rest.next_before_id is None
    everyone = store.policies.page(limit=10, before_id=None)
    assert [p.id for p in everyone.policies] == [theirs, *reversed(mine)]


def test_a_deleted_policy_is_gone_and_its_id_is_never_given_again(store: JobStore) -> None:
    older, newest = add(store), add(store)
    store.policies.delete(newest)
    for read in (store.policies.get, store.policies.table, store.policies.delete):
        with pytest.raises(PolicyNotFound):
            read(newest)
    assert store.policies.owner_of(newest) is None
    assert store.policies.get(older).id == older
    assert add(store) > newest


def test_a_key_that_still_holds_gives_back_the_policy_it_kept(store: JobStore) -> None:
    states, actions = qlearning.labels("behaviors")
    values = np.zeros((len(states), len(actions)))
    key = Idempotency(key="run-7", digest="d" * 64, ttl_s=60)

    def send(owner: str, idempotency: Idempotency) -> int:
        return store.policies.add(
            action_set="behaviors", communication=("none",), states=states, actions=actions,
            values=values, owner=owner, idempotency=idempotency,
        ).id  # fmt: skip

    first = send("o" * 64, key)
    assert send("o" * 64, key) == first
    assert send("p" * 64, key) != first, "keys are per owner"
    with pytest.raises(IdempotencyKeyReused, match=f"it made policy {first}"):
        send("o" * 64, Idempotency(key="run-7", digest="e" * 64, ttl_s=60))
    assert len(store.policies.page(limit=10, before_id=None).policies) == 2


def test_an_owner_keeps_at_most_its_limit_of_policies(store: JobStore) -> None:
    states, actions = qlearning.labels("behaviors")
    values = np.zeros((len(states), len(actions)))

    def send(owner: str) -> int:
        return store.policies.add(
            action_set="behaviors", communication=("none",), states=states, actions=actions,
            values=values, owner=owner, limit=2,
        ).id  # fmt: skip

    kept = [send("o" * 64), send("o" * 64)]
    with pytest.raises(PolicyLimitReached, match="already keeps 2 policies"):
        send("o" * 64)
    send("p" * 64)
    store.policies.delete(kept[0])
    send("o" * 64)


def test_a_policy_that_active_jobs_evaluate_is_not_deleted(store: JobStore) -> None:
    policy_id = add(store)
    other = add(store)
    scenario = {"policy_from": policy_name(policy_id)}
    jobs = [store.enqueue(scenario, robot_steps=1, episodes=1).id for _ in range(7)]
    store.enqueue({"policy_from": policy_name(other)}, robot_steps=1, episodes=1)
    store.enqueue({}, robot_steps=1, episodes=1)
    with pytest.raises(PolicyInUse) as refused:
        store.policies.delete(policy_id)
    assert refused.value.job_ids == jobs[:5]
    assert "by 7 queued or running job(s) (" + ", ".join(map(str, jobs[:5])) + ", ...)" in str(
        refused.value
    )
    for job_id in jobs:
        store.cancel(job_id)
    store.policies.delete(policy_id)
    with pytest.raises(PolicyNotFound):
        store.policies.get(policy_id)
