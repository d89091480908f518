"""``nanonav submit``, ``study``, ``fetch``, ``jobs`` and ``delete``: the commands that talk to a
running API through ``nanonav.client`` (``policies.py`` has those that send and list policies).

Waiting polls the server and draws a progress bar on stderr when it is a terminal. Ctrl-C stops
the waiting, not the work: the job or study goes on on the server."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, get_args

from nanonav.cli.common import (
    EXIT_OK,
    Failed,
    Subcommands,
    UsageError,
    add_set_option,
    add_url,
    connect,
    positive,
    read_json_object,
    with_settings,
)
from nanonav.cli.tables import format_jobs, format_study, format_table, plural, study_counts
from nanonav.client import (
    JOB_PICTURES,
    QTABLE_PICTURES,
    SWARM_PICTURES,
    ApiError,
    Client,
    Job,
    Policy,
    Status,
    Study,
)
from nanonav.scenario import PRESETS

JOB_POLL_S = 0.25
STUDY_POLL_S = 0.5
WAIT_HELP = (
    "show progress until it has finished; Ctrl-C stops waiting (exit 130) and leaves it running "
    "on the server"
)


@contextmanager
def _bar(total: float, unit: str) -> Iterator[Callable[[float, str], None]]:
    """``show(done, words)`` moves a bar on stderr if it is a terminal, else does nothing."""
    if not sys.stderr.isatty():
        yield lambda done, words: None
        return
    from tqdm import tqdm

    if unit == "fraction":
        layout = "{percentage:3.0f}%|{bar}| {desc} [{elapsed}]"
    else:
        layout = "{n:.0f}/{total:.0f} " + unit + " |{bar}| {desc} [{elapsed}]"
    bar = tqdm(total=total, file=sys.stderr, bar_format=layout, leave=False)

    def show(done: float, words: str) -> None:
        bar.n = done
        bar.set_description_str(words, refresh=True)

    try:
        yield show
    finally:
        bar.close()


@contextmanager
def _goes_on(kind: str, ident: int, url: str) -> Iterator[None]:
    """A Ctrl-C within says where the job or study that exists goes on (one said by a block
    within passes as it is)."""
    try:
        yield
    except KeyboardInterrupt as stop:
        if str(stop):
            raise
        raise KeyboardInterrupt(
            f"stopped waiting; {kind} {ident} goes on on the server ({url}/{kind}s/{ident})"
        ) from None


# ---------------------------------------------------------------- submit


def add_submit(subcommands: Subcommands) -> None:
    submit = subcommands.add_parser(
        "submit",
        help="queue a scenario on a server (and wait for its Table 1)",
        description="Queue a scenario on a running API and print the job's id. The scenario "
        "is read from FILE, then --set, --preset and --seed override it; the server validates "
        "it. "
        "With --wait, print the job's Table 1 once it has succeeded; exit 1 if it failed or "
        "was cancelled.",
    )
    submit.add_argument(
        "file", nargs="?", type=Path, metavar="FILE", help="scenario as a JSON object"
    )
    submit.add_argument(
        "--preset",
        choices=sorted(PRESETS),
        help="base values (explicit fields of FILE override them)",
    )
    submit.add_argument("--seed", type=int, metavar="N", help="seed of every random draw")
    add_set_option(submit, "FILE's")
    submit.add_argument("--wait", action="store_true", help=WAIT_HELP)
    add_url(submit)
    submit.set_defaults(handler=_submit)


def _submit(args: argparse.Namespace) -> int:
    if args.file is None and args.preset is None:
        raise UsageError(["give a scenario FILE or --preset NAME"])
    scenario = {} if args.file is None else read_json_object(args.file, "scenario")
    with_settings(scenario, args.settings)
    if args.preset is not None:
        scenario["preset"] = args.preset
    if args.seed is not None:
        scenario["seed"] = args.seed
    with connect(args) as api:
        job = api.submit(scenario)
        with _goes_on("job", job.id, api.url):  # from the moment it exists, however soon
            print(f"job {job.id} {job.status} (seed {job.scenario.get('seed')})", flush=True)
            if not args.wait:
                return EXIT_OK
            job = wait_job(api, job.id)
        if job.status != "succeeded":
            raise Failed([f"job {job.id} {job.status}" + (f": {job.error}" if job.error else "")])
        print()
        print(format_table(api.metrics(job.id), sent_policy(api, job.scenario)))
    return EXIT_OK


def sent_policy(api: Client, scenario: dict[str, Any]) -> Policy | None:
    """The policy sent to the service that ``scenario``'s ``policy_from`` names, to name it by
    its name and kind; None for any other, or one deleted since."""
    source = scenario.get("policy_from")
    if not isinstance(source, str):
        return None
    try:
        return api.policy(source)
    except ApiError as error:
        if error.status == 404:
            return None
        raise


def _job_words(job: Job) -> str:
    if job.cancel_requested and not job.finished:
        return "cancelling"
    if job.status == "running":
        return f"episode {min(job.episode + 1, job.episodes)}/{job.episodes}"
    return job.status


def wait_job(api: Client, job_id: int) -> Job:
    """The job once it has finished, with a bar meanwhile."""
    with _bar(1.0, "fraction") as show, _goes_on("job", job_id, api.url):
        return api.wait(
            job_id, poll_s=JOB_POLL_S, on_progress=lambda j: show(j.progress, _job_words(j))
        )


# ---------------------------------------------------------------- study


def add_study(subcommands: Subcommands) -> None:
    study = subcommands.add_parser(
        "study",
        help="queue a grid of scenarios x seeds, or show a study",
        description="Queue a study on a running API: FILE is a JSON object with 'name', "
        "'base' (a scenario), 'grid' (scenario fields by dotted name, each with the values to "
        "try), 'seeds' or 'replicates', and optionally 'compare' (a grid key whose values are "
        "compared seed by seed with the first). With --id, show an existing study instead; "
        "with --id and --retry, queue its failed jobs again first. "
        "The table gives, per grid point and metric, n, the mean and its 95% CI, and with "
        "'compare' the paired differences with their CI and p-value. With --wait, exit 1 "
        "unless every job succeeded.",
    )
    study.add_argument("file", nargs="?", type=Path, metavar="FILE", help="the study as JSON")
    study.add_argument("--id", type=positive, metavar="ID", help="an existing study's id")
    study.add_argument(
        "--retry", action="store_true", help="with --id: queue the study's failed jobs again"
    )
    study.add_argument("--wait", action="store_true", help=WAIT_HELP)
    add_url(study)
    study.set_defaults(handler=_study)


def _study(args: argparse.Namespace) -> int:
    if (args.file is None) == (args.id is None):
        raise UsageError(["give a study FILE to submit, or --id ID to show one (not both)"])
    if args.retry and args.id is None:
        raise UsageError(["--retry needs --id ID: the study whose failed jobs to queue again"])
    with connect(args) as api:
        if args.retry:
            failed = api.study(args.id).jobs.failed
            retried = api.retry_study(args.id)
            print(f"study {retried.id} {retried.status}: {plural(failed, 'failed job')} "
                  "queued again", flush=True)  # fmt: skip
        if args.file is not None:
            created = api.submit_study(read_json_object(args.file, "study"))
            seeds = len(created.spec.get("seeds") or [])
            with _goes_on("study", created.id, api.url):  # from the moment it exists
                print(
                    f"study {created.id} {created.status}: {plural(created.jobs.total, 'job')} "
                    f"({plural(len(created.points), 'grid point')} x {plural(seeds, 'seed')})",
                    flush=True,
                )
                if not args.wait:
                    return EXIT_OK
                study = wait_study(api, created.id)
            print()
        else:
            study = wait_study(api, args.id) if args.wait else api.study(args.id)
        print(format_study(study))
    if args.wait and study.status != "succeeded":
        raise Failed([f"study {study.id} {study.status}: {study_counts(study)}"])
    return EXIT_OK


def wait_study(api: Client, study_id: int) -> Study:
    """The study once every job of it has finished, with a bar of jobs finished meanwhile."""
    first = api.study(study_id)
    with _bar(first.jobs.total, "jobs") as show:

        def progress(study: Study) -> None:
            jobs = study.jobs
            show(jobs.finished, f"{jobs.running} running, {jobs.failed} failed")

        with _goes_on("study", study_id, api.url):
            return api.wait_study(study_id, poll_s=STUDY_POLL_S, on_progress=progress)


# ---------------------------------------------------------------- fetch


def add_fetch(subcommands: Subcommands) -> None:
    fetch = subcommands.add_parser(
        "fetch",
        help="download a job's or a study's results into a directory",
        description="Write a succeeded job's metrics.json, trajectory.npz, trajectory.xyz "
        "(extended XYZ, for OVITO, ParaView, VMD or ASE), qtable.json and "
        "every picture (<name>.png; qtable.png if it learned a Q-table) into DIR; or, with "
        "--study, a study's results.csv, results.parquet, comparisons.csv and comparisons.parquet "
        "(if it compares), study.json and its pictures; or, "
        "with --policy, a policy's policy.json (its table, which `nanonav policy` sends "
        "again; a network's labels) and a network's policy.onnx. DIR is created if missing.",
    )
    _add_one_of(fetch)
    fetch.add_argument("--out", type=Path, metavar="DIR", required=True, help="where to write")
    add_url(fetch)
    fetch.set_defaults(handler=_fetch)


def _add_one_of(parser: argparse.ArgumentParser) -> None:
    """What ``fetch`` and ``delete`` act on: a job, a study or a policy (``_one_of`` checks)."""
    parser.add_argument("id", nargs="?", type=positive, metavar="ID", help="a job's id")
    parser.add_argument("--study", type=positive, metavar="ID", help="a study's id instead")
    parser.add_argument("--policy", type=positive, metavar="ID", help="a policy's id instead")


def _one_of(args: argparse.Namespace) -> None:
    if sum(ident is not None for ident in (args.id, args.study, args.policy)) != 1:
        raise UsageError(["give a job ID, or --study ID, or --policy ID (one of them)"])


def _fetch(args: argparse.Namespace) -> int:
    """Each file said as it is written (a picture the server has not drawn yet takes seconds,
    and a study has a dozen), then how many."""
    _one_of(args)
    with connect(args) as api:
        if args.study is not None:
            what, found = f"study {args.study}", _study_files(api, args.study)
        elif args.policy is not None:
            what, found = f"policy {args.policy}", _policy_files(api, args.policy)
        else:
            what, found = f"job {args.id}", _job_files(api, args.id)

        def each(path: Path) -> None:
            print(f"  {path.name:<28} {_size(path.stat().st_size):>9}", flush=True)

        def first() -> None:
            print(f"Fetching {what} into {args.out}:", flush=True)

        written = _write(args.out, found, each, first)
    print(f"Wrote {plural(len(written), 'file')} to {args.out}")
    return EXIT_OK


def _policy_files(api: Client, policy_id: int) -> Iterator[tuple[str, bytes]]:
    """A policy's document, and a network's model."""
    policy = api.policy(policy_id)
    yield "policy.json", _document(policy.raw)
    if policy.kind == "network":
        yield "policy.onnx", api.network_model(policy_id)


def add_delete(subcommands: Subcommands) -> None:
    delete = subcommands.add_parser(
        "delete",
        help="delete a finished job, an ended study or a policy",
        description="Delete a finished job (succeeded, failed or cancelled) with its results "
        "and pictures; or, with --study, an ended study with its jobs; or, with --policy, a "
        "policy. A queued or running job or study is refused (cancel it first), and so are a "
        "job of a study (delete the study) and a policy that queued or running jobs evaluate.",
    )
    _add_one_of(delete)
    add_url(delete)
    delete.set_defaults(handler=_delete)


def _delete(args: argparse.Namespace) -> int:
    _one_of(args)
    with connect(args) as api:
        if args.study is not None:
            api.delete_study(args.study)
            print(f"Deleted study {args.study} and its jobs")
        elif args.policy is not None:
            api.delete_policy(args.policy)
            print(f"Deleted policy {args.policy}")
        else:
            api.delete(args.id)
            print(f"Deleted job {args.id}")
    return EXIT_OK


def _document(data: Any) -> bytes:
    return (json.dumps(data, indent=2) + "\n").encode()


def _job_files(api: Client, job_id: int) -> Iterator[tuple[str, bytes]]:
    job = api.job(job_id)
    if job.status != "succeeded":
        if not job.finished:
            raise UsageError([f"job {job_id} has no results yet: it is {job.status}"])
        ended = "it failed" if job.status == "failed" else "it was cancelled"
        why = f" ({job.error})" if job.error else ""
        raise UsageError([f"job {job_id} has no results: {ended}{why}"])
    yield "metrics.json", _document(api.metrics(job_id))
    yield "trajectory.npz", api.trajectory_npz(job_id)
    yield "trajectory.xyz", api.trajectory_xyz(job_id)
    if job.links.get("qtable"):
        yield "qtable.json", _document(api.qtable(job_id))
    plots = job.links.get("plots") or {}
    for name in JOB_PICTURES:
        if name in QTABLE_PICTURES and name not in plots:
            continue  # a fixed rule, a network or an untrained learner has no table to draw
        if name in SWARM_PICTURES and name not in plots:
            continue  # a run of lone robots has no treatment to draw
        yield f"{name}.png", api.picture(job_id, name)


def _study_files(api: Client, study_id: int) -> Iterator[tuple[str, bytes]]:
    study = api.study(study_id)
    if not study.finished:
        print(
            f"nanonav fetch: study {study_id} is {study.status}: the files show it as it is now",
            file=sys.stderr,
        )
    yield "results.csv", api.study_csv(study_id)
    yield "results.parquet", api.study_parquet(study_id)
    if study.spec.get("compare") is not None:
        yield "comparisons.csv", api.study_comparisons_csv(study_id)
        yield "comparisons.parquet", api.study_comparisons_parquet(study_id)
    yield "study.json", _document(study.raw)
    for name in study.links.get("plots") or {}:
        yield f"{name}.png", api.study_picture(study_id, name)


def _write(
    out: Path,
    files: Iterator[tuple[str, bytes]],
    each: Callable[[Path], None] = lambda _: None,
    first: Callable[[], None] = lambda: None,
) -> list[Path]:
    """Each file as it comes, told to ``each`` once written; the directory made once the first
    one has downloaded (so a job without results leaves no empty directory behind), when
    ``first`` is told."""
    written: list[Path] = []
    for name, content in files:
        if not written:
            try:
                out.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise UsageError([f"cannot create {out}: {error}"]) from error
            first()
        path = out / name
        try:
            path.write_bytes(content)
        except OSError as error:
            raise UsageError([f"cannot write {path}: {error}"]) from error
        written.append(path)
        each(path)
    return written


def _size(count: int) -> str:
    return f"{count} B" if count < 1000 else f"{count / 1000:,.1f} kB"


# ---------------------------------------------------------------- jobs


def add_jobs(subcommands: Subcommands) -> None:
    jobs = subcommands.add_parser(
        "jobs",
        help="list a server's jobs, newest first",
        description="List jobs newest first: id, status, progress, policy, robots, seed, study "
        "and when each came (local time).",
    )
    jobs.add_argument("--status", choices=get_args(Status), help="only jobs in this state")
    jobs.add_argument("--study", type=positive, metavar="ID", help="only this study's jobs")
    jobs.add_argument(
        "--limit", type=positive, default=20, metavar="N", help="at most N jobs (default 20)"
    )
    add_url(jobs)
    jobs.set_defaults(handler=_jobs)


def _jobs(args: argparse.Namespace) -> int:
    with connect(args) as api:
        found = list(api.jobs(status=args.status, study=args.study, limit=args.limit))
    if not found:
        print("no jobs")
    else:
        print(format_jobs(found))
    return EXIT_OK
