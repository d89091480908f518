"""``nanonav policy`` and ``nanonav policies``: Q-tables and networks made elsewhere, sent to a
running API for scenarios to evaluate (``policy_from``), and listed.

A network is an ONNX model (``.onnx``: ``nanonav train``'s policy.onnx, or one exported by
torch), sent as it is; the labels of its observation and actions come from its metadata or from
``--observation`` and ``--actions``.

A table is read from a file as the service and the environments write one: a JSON object with
``states``, ``actions`` and ``values`` or ``greedy`` (a ``POST /policies`` body, a job's
``qtable.json`` or a policy's ``policy.json`` as ``nanonav fetch`` writes them), or an ``.npz``
with the arrays ``states``, ``actions`` and ``values`` (``numpy.savez`` of an environment's
``state_labels``, ``action_labels`` and the table trained on it)."""

from __future__ import annotations

import argparse
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from nanonav.cli.common import (
    EXIT_OK,
    Subcommands,
    UsageError,
    add_url,
    connect,
    positive,
    read_json_object,
)
from nanonav.cli.tables import format_policies

# What a file's object may carry to the server; the rest (a job's visits, a policy's id and
# links) is what the service said of a table, not the table.
SENT = ("states", "actions", "values", "greedy", "name")


def add_policy(subcommands: Subcommands) -> None:
    policy = subcommands.add_parser(
        "policy",
        help="send a Q-table or a network made elsewhere, for scenarios to evaluate",
        description="Send the Q-table or network in FILE to a running API and print the "
        "policy_from that names it (policy-<id>): a job or a study evaluates it with that "
        "policy_from and learning.episodes 0. FILE is JSON with 'states', 'actions' and "
        "'values' or 'greedy' (a POST /policies body, or a qtable.json or policy.json that "
        "`nanonav fetch` wrote: their values are sent), an .npz with the arrays states, "
        "actions and values, or an .onnx model (observation -> action logits or actions; "
        "`nanonav train` writes one, policy.onnx).",
    )
    policy.add_argument(
        "file", type=Path, metavar="FILE", help="the table, .json or .npz, or the network, .onnx"
    )
    policy.add_argument(
        "--observation", metavar="LABELS",
        help="an .onnx model's input columns, comma-separated (an environment's "
        "observation_labels; default: the model's metadata)",
    )  # fmt: skip
    policy.add_argument(
        "--actions", metavar="LABELS",
        help="an .onnx model's actions, comma-separated (default: the model's metadata)",
    )  # fmt: skip
    policy.add_argument(
        "--name", metavar="NAME",
        help="what lists call it (default: FILE's; for a network nanonav train wrote, its run's "
        "folder, learner and decisions)",
    )  # fmt: skip
    policy.add_argument(
        "--idempotency-key",
        metavar="KEY",
        help="send again with the same KEY to get the same policy back, not a second one",
    )
    add_url(policy)
    policy.set_defaults(handler=_policy)


def _policy(args: argparse.Namespace) -> int:
    if args.file.suffix == ".onnx":
        return _network(args)
    if args.observation is not None or args.actions is not None:
        raise UsageError(["--observation and --actions are an .onnx model's"])
    table = read_table(args.file)
    if args.name is not None:
        table["name"] = args.name
    with connect(args) as api:
        sent = api.send_policy(
            table["states"],
            table["actions"],
            values=table.get("values"),
            greedy=table.get("greedy"),
            name=table.get("name"),
            idempotency_key=args.idempotency_key,
        )
    robots = f", one per robot of {sent.table_count}" if sent.per_robot else ""
    print(
        f"policy {sent.id}: policy_from {sent.policy_from!r} ({sent.action_set} actions, "
        f"{sent.state_count} states x {sent.action_count} actions{robots})"
    )
    return EXIT_OK


def _network(args: argparse.Namespace) -> int:
    try:
        model = args.file.read_bytes()
    except OSError as error:
        raise UsageError([f"cannot read {args.file}: {error.strerror}"]) from None

    def labels(text: str | None) -> list[str] | None:
        return None if text is None else [part.strip() for part in text.split(",")]

    with connect(args) as api:
        sent = api.send_network(
            model,
            observation=labels(args.observation),
            actions=labels(args.actions),
            name=args.name or network_name(args.file),
            idempotency_key=args.idempotency_key,
        )
    print(
        f"policy {sent.id}: policy_from {sent.policy_from!r} (a network: {sent.state_count} "
        f"observation columns -> {sent.action_count} {sent.action_set} actions)"
    )
    return EXIT_OK


def network_name(path: Path) -> str:
    """What a network is called when no ``--name`` is given: a file ``nanonav train`` wrote
    (its ``training.json`` beside it) by its run's folder, its learner and its decisions
    (``gru: recurrent-ppo, 10,000,000 decisions``), not by the stem every such file shares
    (``policy``); any other file by its stem."""
    report = path.parent / "training.json"
    try:
        trained = json.loads(report.read_text(encoding="utf-8"))
        decisions = int(trained["decisions"])
        return f"{path.resolve().parent.name}: {trained['algo']}, {decisions:,} decisions"
    except (OSError, ValueError, KeyError, TypeError):
        return path.stem


def read_table(path: Path) -> dict[str, Any]:
    """What of ``path`` is sent: its labels, and its values, else its greedy table, and its
    name if it has one; a file that holds no table is a ``UsageError`` naming what it lacks."""
    if path.suffix == ".npz":
        table = _npz(path)
    else:
        found = read_json_object(path, "table")
        table = {key: found[key] for key in SENT if key in found}
        if "values" in table and "greedy" in table:
            del table["greedy"]  # a qtable.json or policy.json: the exact table, not its argmax
    missing = [key for key in ("states", "actions") if key not in table]
    if missing:
        raise UsageError([f"{path}: no {' or '.join(missing)}: not a table's labels"])
    if "values" not in table and "greedy" not in table:
        raise UsageError([f"{path}: neither values nor greedy: no table to send"])
    if not table["states"]:
        raise UsageError([f"{path}: no states: a policy that learns no table has none to send"])
    table.setdefault("name", path.stem)
    return table


def _npz(path: Path) -> dict[str, Any]:
    try:
        with np.load(path, allow_pickle=False) as arrays:
            found = {key: arrays[key] for key in ("states", "actions", "values") if key in arrays}
    except (OSError, ValueError, zipfile.BadZipFile) as error:
        raise UsageError([f"cannot read {path} as .npz: {error}"]) from error
    missing = [key for key in ("states", "actions", "values") if key not in found]
    if missing:
        raise UsageError([f"{path}: no array {', '.join(missing)} (it has {', '.join(found)})"])
    return {
        "states": [str(label) for label in found["states"].tolist()],
        "actions": [str(label) for label in found["actions"].tolist()],
        "values": found["values"],
    }


def add_policies(subcommands: Subcommands) -> None:
    policies = subcommands.add_parser(
        "policies",
        help="list a server's policies, newest first",
        description="List the policies sent to a server, newest first: id, the policy_from "
        "that names it, its name, the action set and communication models it is for, its "
        "table's shape and when it came (local time). `nanonav fetch --policy ID` writes one "
        "with its table; `nanonav delete --policy ID` deletes one.",
    )
    policies.add_argument(
        "--limit", type=positive, default=20, metavar="N", help="at most N (default 20)"
    )
    add_url(policies)
    policies.set_defaults(handler=_policies)


def _policies(args: argparse.Namespace) -> int:
    with connect(args) as api:
        found = list(api.policies(limit=args.limit))
    print(format_policies(found) if found else "no policies")
    return EXIT_OK
