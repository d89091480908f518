"""A synchronous client for the NanoNav job service, for scripts and the ``nanonav`` command.

```python
from nanonav.client import Client

with Client("http://127.0.0.1:8000") as api:  # default: $NANONAV_URL, else that URL
    job = api.wait(api.submit({"preset": "paper-single", "seed": 7}).id)
    print(job.status, api.metrics(job.id)["summary"]["total_steps"])
```

Answers come back as small frozen dataclasses (``Job``, ``Study``, ...) with the fields a script
needs and the whole JSON answer in ``raw``. Every answer that is not 2xx raises ``ApiError``, with
the fields of the server's problem document; a server that cannot be reached raises
``ServerUnreachable``, a subclass of ``ApiError`` with ``status`` 0, so one ``except ApiError``
catches every failure of a call. This module speaks HTTP only: it imports neither the service nor
the worker, nor the engine.
"""

from __future__ import annotations

import base64
import csv
import functools
import io
import os
import ssl
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar

import httpx
import numpy as np
from numpy.typing import NDArray

import nanonav
from nanonav.client.answers import Comparison as Comparison
from nanonav.client.answers import Difference as Difference
from nanonav.client.answers import GridValue as GridValue
from nanonav.client.answers import Interval as Interval
from nanonav.client.answers import Job as Job
from nanonav.client.answers import JobCounts as JobCounts
from nanonav.client.answers import Policy as Policy
from nanonav.client.answers import PolicyDetail as PolicyDetail
from nanonav.client.answers import Study as Study
from nanonav.client.answers import StudyPoint as StudyPoint
from nanonav.client.answers import StudySummary as StudySummary
from nanonav.client.answers import parse_cell as parse_cell
from nanonav.client.errors import ApiError as ApiError
from nanonav.client.errors import ServerUnreachable as ServerUnreachable
from nanonav.status import Status as Status  # a public name of the client too

# A job's pictures by name: the path under /jobs/{id}/ and its query.
JOB_PICTURES: dict[str, tuple[str, dict[str, str]]] = {
    **{f"heatmap_{p}": ("heatmap.png", {"plane": p}) for p in ("xy", "xz", "yz", "all")},
    **{
        name: (f"plots/{name}.png", {})
        for name in ("trajectory", "concentration", "learning", "qtable", "treatment")
    },
}
# Pictures only a job whose policy learns a Q-table has; others answer 404 for them.
QTABLE_PICTURES = frozenset({"qtable"})
# Pictures only a job whose run reports the swarm's numbers has (its links name them).
SWARM_PICTURES = frozenset({"treatment"})
PAGE_SIZE = 100  # the most the API lists per page

_T = TypeVar("_T")


@functools.cache
def tls_context() -> ssl.SSLContext:
    """httpx's default TLS settings (its CA bundle, or SSL_CERT_FILE and SSL_CERT_DIR), built
    once a process: building them loads the CA bundle, 23 ms that a script or a command that
    makes many clients paid for each."""
    return httpx.create_ssl_context()


class Client:
    """One connection pool to one API. Use it in a ``with`` block, or ``close()`` it."""

    def __init__(
        self,
        url: str | None = None,
        *,
        timeout: float = 30.0,
        transport: httpx.BaseTransport | None = None,
        api_key: str | None = None,
    ) -> None:
        if url is None or api_key is None:
            from nanonav.settings import ClientSettings

            settings = ClientSettings()
            url = settings.url if url is None else url
            if api_key is None and settings.api_key is not None:
                api_key = settings.api_key.get_secret_value()
        self.url = url.rstrip("/")
        # X-Requested-With marks the requests as a script's, which a cross-site form's are not.
        headers = {"User-Agent": f"nanonav-client/{nanonav.__version__}",
                   "X-Requested-With": "nanonav-client"}  # fmt: skip
        if api_key:
            headers["Authorization"] = f"Bearer {api_key}"
        self._http = httpx.Client(base_url=self.url, timeout=timeout, transport=transport,
                                  headers=headers, verify=tls_context())  # fmt: skip

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        self._http.close()

    # ------------------------------------------------------------ jobs

    def submit(
        self,
        scenario: Mapping[str, Any] | None = None,
        *,
        idempotency_key: str | None = None,
        callback_url: str | None = None,
    ) -> Job:
        """Queue a scenario (``None`` or ``{}``: all defaults). The same ``idempotency_key``
        again answers with the job it made the first time, so a retry never runs twice; a
        ``callback_url`` is sent a signed summary when the job ends."""
        data = self._json(
            "POST",
            "/jobs",
            json=dict(scenario or {}),
            key=idempotency_key,
            params=_callback(callback_url),
        )
        return Job.of(data)

    def job(self, job_id: int) -> Job:
        return Job.of(self._json("GET", f"/jobs/{job_id}"))

    def jobs(
        self,
        *,
        status: Status | None = None,
        study: int | None = None,
        limit: int | None = None,
    ) -> Iterator[Job]:
        """Jobs newest first, page after page until ``limit`` jobs (or all of them)."""
        params: dict[str, Any] = {"limit": PAGE_SIZE if limit is None else min(limit, PAGE_SIZE)}
        if status is not None:
            params["status"] = status
        if study is not None:
            params["study"] = study
        pages = self._pages("/jobs", params, "jobs")
        yield from _capped((Job.of(item) for item in pages), limit)

    def wait(
        self,
        job_id: int,
        *,
        poll_s: float = 0.5,
        timeout_s: float | None = None,
        on_progress: Callable[[Job], None] | None = None,
    ) -> Job:
        """Poll the job until it has finished (succeeded, failed or cancelled) and return it;
        ``on_progress`` sees every state polled. Raises ``TimeoutError`` after ``timeout_s``."""
        return _poll(lambda: self.job(job_id), f"job {job_id}", poll_s, timeout_s, on_progress)

    def cancel(self, job_id: int) -> Job:
        """Cancel a job: a queued one at once, a running one within about a second (409 if it
        has already finished)."""
        return Job.of(self._json("POST", f"/jobs/{job_id}/cancel"))

    def delete(self, job_id: int) -> None:
        """Delete a finished job with its results and pictures (409 if it is queued or running,
        or belongs to a study; 404 if there is no such job, or no more)."""
        self._request("DELETE", f"/jobs/{job_id}")

    def metrics(self, job_id: int) -> dict[str, Any]:
        """Table 1 (``summary``), one row per robot, the learning curve, the scenario."""
        return self._json("GET", f"/jobs/{job_id}/metrics")

    def trajectory_npz(self, job_id: int, *, stride: int = 1) -> bytes:
        """The evaluation episode as an ``.npz`` file, every ``stride``-th step."""
        params = {"format": "npz", "stride": stride}
        return self._request("GET", f"/jobs/{job_id}/trajectory", params=params).content

    def trajectory_xyz(self, job_id: int, *, stride: int = 1) -> bytes:
        """The evaluation episode as extended XYZ (a frame per ``stride``-th step: robots,
        cells and obstacles, in the physics' units), which OVITO, ParaView, VMD and ASE open
        (``nanonav.extxyz``)."""
        params = {"format": "xyz", "stride": stride}
        return self._request("GET", f"/jobs/{job_id}/trajectory", params=params).content

    def arrays(self, job_id: int, *, stride: int = 1) -> dict[str, NDArray[Any]]:
        """The evaluation episode's arrays (``robots`` is ``(steps, robots, 3)``, ...)."""
        blob = self.trajectory_npz(job_id, stride=stride)
        with np.load(io.BytesIO(blob), allow_pickle=False) as loaded:
            return {name: loaded[name] for name in loaded.files}

    def qtable(self, job_id: int) -> dict[str, Any]:
        """The learned Q-table: ``states``, ``actions``, ``values``, ``visits``, and ``greedy``,
        the greedy action of every state. A job without one (a fixed rule, a network, 0
        training episodes) raises ApiError 404 ``no-qtable``; its ``links["qtable"]`` is None."""
        return self._json("GET", f"/jobs/{job_id}/qtable")

    def picture(
        self, job_id: int, name: str, *, at: float | None = None, resolution: int | None = None
    ) -> bytes:
        """A PNG of a succeeded job; ``name`` is one of ``JOB_PICTURES`` (``qtable`` answers
        404 for a job whose policy learns no Q-table). A heatmap takes ``at``, where its slice
        cuts the plane's normal axis, and ``resolution``, its pixels per side (20 to 400)."""
        if name not in JOB_PICTURES:
            raise ValueError(f"no picture {name!r}; there are {', '.join(JOB_PICTURES)}")
        path, fixed = JOB_PICTURES[name]
        params: dict[str, str | float | int] = dict(fixed)
        if at is not None or resolution is not None:
            if not name.startswith("heatmap_"):
                raise ValueError(f"only heatmaps take at and resolution, not {name!r}")
            params.update(
                {k: v for k, v in (("at", at), ("resolution", resolution)) if v is not None}
            )
        return self._request("GET", f"/jobs/{job_id}/{path}", params=params).content

    # ------------------------------------------------------------ studies

    def submit_study(
        self,
        spec: Mapping[str, Any],
        *,
        idempotency_key: str | None = None,
        callback_url: str | None = None,
    ) -> Study:
        """Queue every grid point x seed of ``spec`` (``name``, ``base``, ``grid``, ``seeds``
        or ``replicates``, ``compare``) as jobs, all or none; a ``callback_url`` is sent a
        signed summary when the last one ends."""
        data = self._json(
            "POST", "/studies", json=dict(spec), key=idempotency_key, params=_callback(callback_url)
        )
        return Study.of(data)

    def callback(self, job_id: int) -> dict[str, Any]:
        """How sending a job's webhook went (``state``, ``attempts``, ``last_error``...)."""
        return self._json("GET", f"/jobs/{job_id}/callback")

    def study_callback(self, study_id: int) -> dict[str, Any]:
        return self._json("GET", f"/studies/{study_id}/callback")

    def study(self, study_id: int) -> Study:
        return Study.of(self._json("GET", f"/studies/{study_id}"))

    def studies(self, *, limit: int | None = None) -> Iterator[StudySummary]:
        """Studies newest first, without their statistics (``study(id)`` has them)."""
        params = {"limit": PAGE_SIZE if limit is None else min(limit, PAGE_SIZE)}
        pages = self._pages("/studies", params, "studies")
        yield from _capped((StudySummary.of(item) for item in pages), limit)

    def wait_study(
        self,
        study_id: int,
        *,
        poll_s: float = 1.0,
        timeout_s: float | None = None,
        on_progress: Callable[[Study], None] | None = None,
    ) -> Study:
        """Poll the study until every job of it has finished and return it with its final
        statistics. Raises ``TimeoutError`` after ``timeout_s``."""
        return _poll(
            lambda: self.study(study_id), f"study {study_id}", poll_s, timeout_s, on_progress
        )

    def cancel_study(self, study_id: int) -> Study:
        """Cancel a study's unfinished jobs (409 if it has already finished)."""
        return Study.of(self._json("POST", f"/studies/{study_id}/cancel"))

    def retry_study(self, study_id: int) -> Study:
        """Queue the study's failed jobs again, on their scenarios and seeds (409 if none
        failed)."""
        return Study.of(self._json("POST", f"/studies/{study_id}/retry"))

    def delete_study(self, study_id: int) -> None:
        """Delete an ended study with its jobs and their results (409 while any of its jobs is
        queued or running; 404 if there is no such study, or no more)."""
        self._request("DELETE", f"/studies/{study_id}")

    def study_csv(self, study_id: int) -> bytes:
        """The study's table as the server writes it: a row per job, metrics empty unless the
        job succeeded."""
        return self._request("GET", f"/studies/{study_id}/results.csv").content

    def study_table(self, study_id: int) -> list[dict[str, Any]]:
        """The study's table, a dict per job, cells parsed as ``parse_cell`` says."""
        text = self.study_csv(study_id).decode("utf-8")
        return [
            {key: parse_cell(value) for key, value in row.items()}
            for row in csv.DictReader(io.StringIO(text))
        ]

    def write_study_csv(self, study_id: int, path: str | Path) -> Path:
        """Save the study's table to ``path``, byte for byte as served; returns the path."""
        target = Path(path)
        target.write_bytes(self.study_csv(study_id))
        return target

    def study_parquet(self, study_id: int) -> bytes:
        """The study's table as a Parquet file (ids and seeds int64, metrics float64)."""
        params = {"format": "parquet"}
        return self._request("GET", f"/studies/{study_id}/results.csv", params=params).content

    def study_comparisons_csv(self, study_id: int) -> bytes:
        """The study's paired comparisons as the server writes them: a row per difference
        (method against baseline, in one metric) with p_value beside p_holm; no rows unless
        the study compares."""
        return self._request("GET", f"/studies/{study_id}/comparisons.csv").content

    def study_comparisons(self, study_id: int) -> list[dict[str, Any]]:
        """The study's paired comparisons, a dict per difference, cells parsed as
        ``parse_cell`` says."""
        text = self.study_comparisons_csv(study_id).decode("utf-8")
        return [
            {key: parse_cell(value) for key, value in row.items()}
            for row in csv.DictReader(io.StringIO(text))
        ]

    def study_comparisons_parquet(self, study_id: int) -> bytes:
        """The study's paired comparisons as a Parquet file (n and holm_comparisons int64,
        the statistics float64)."""
        params = {"format": "parquet"}
        return self._request("GET", f"/studies/{study_id}/comparisons.csv", params=params).content

    def study_picture(self, study_id: int, name: str) -> bytes:
        """A PNG: a metric's means and CIs across the grid (``name`` is a metric, as in
        ``Study.metrics``), ``learning`` for the mean learning curves, or ``policies`` for
        what its learning points learned (when its links name it)."""
        return self._request("GET", f"/studies/{study_id}/plots/{name}.png").content

    # ------------------------------------------------------------ policies

    def send_policy(
        self,
        states: Sequence[str],
        actions: Sequence[str],
        *,
        values: NDArray[Any] | Sequence[Any] | None = None,
        greedy: Sequence[Mapping[str, Any]] | None = None,
        name: str | None = None,
        idempotency_key: str | None = None,
    ) -> Policy:
        """Send a Q-table made elsewhere: ``states`` and ``actions`` label its rows and columns
        (an environment's ``state_labels`` and ``action_labels``), and the table is ``values``
        (states x actions, or robots x states x actions) or ``greedy`` (``{"state", "action"}``
        items, as ``qtable(job_id)["greedy"]`` has them), one of the two. A scenario evaluates
        it with ``policy_from`` set to the answer's ``policy_from``. The same
        ``idempotency_key`` again answers with the policy it kept the first time."""
        body: dict[str, Any] = {"states": list(states), "actions": list(actions)}
        if values is not None:
            try:
                body["values"] = np.asarray(values, dtype=np.float64).tolist()
            except (TypeError, ValueError):
                body["values"] = values  # not a table of numbers: the server says where
        if greedy is not None:
            body["greedy"] = [dict(choice) for choice in greedy]
        if name is not None:
            body["name"] = name
        return Policy.of(self._json("POST", "/policies", json=body, key=idempotency_key))

    def send_network(
        self,
        model: bytes | str | os.PathLike[str],
        *,
        observation: Sequence[str] | None = None,
        actions: Sequence[str] | None = None,
        name: str | None = None,
        idempotency_key: str | None = None,
    ) -> Policy:
        """Send a network: ``model`` is an ONNX model (its bytes, or a file's path) that takes
        a float32 batch of observations and gives action logits or actions. ``observation``
        and ``actions`` name its input columns and its actions (an environment's
        ``observation_labels`` and ``action_labels``); leave them out when the model's metadata
        names them, as ``nanonav train``'s policy.onnx does. The service checks the model and
        runs it once before it keeps it (``ApiError`` 422 saying what is wrong)."""
        data = model if isinstance(model, bytes) else Path(model).read_bytes()
        body: dict[str, Any] = {"onnx": base64.b64encode(data).decode("ascii")}
        if observation is not None:
            body["observation"] = list(observation)
        if actions is not None:
            body["actions"] = list(actions)
        if name is not None:
            body["name"] = name
        return Policy.of(self._json("POST", "/policies", json=body, key=idempotency_key))

    def policy(self, policy_id: int | str) -> PolicyDetail:
        """A policy, by its id or its name (``policy-3``), with its table: ``states``,
        ``actions``, ``values`` and ``greedy``; or a network's ``observation``, ``actions``,
        ``model_bytes`` and cost (``raw`` is the answer as it came)."""
        return PolicyDetail.of(self._json("GET", f"/policies/{policy_id}"))

    def network_model(self, policy_id: int) -> bytes:
        """A network's ONNX model, as it was sent (``ApiError`` 404 for a table)."""
        return self._request("GET", f"/policies/{policy_id}/model").content

    def policies(self, *, limit: int | None = None) -> Iterator[Policy]:
        """Policies newest first, without their tables (``policy(id)`` has them)."""
        params = {"limit": PAGE_SIZE if limit is None else min(limit, PAGE_SIZE)}
        pages = self._pages("/policies", params, "policies")
        yield from _capped((Policy.of(item) for item in pages), limit)

    def delete_policy(self, policy_id: int) -> None:
        """Delete a policy (404 if there is no such policy, or no more; 409 while queued or
        running jobs evaluate it)."""
        self._request("DELETE", f"/policies/{policy_id}")

    # ------------------------------------------------------------ HTTP

    def _request(
        self,
        method: str,
        path: str,
        *,
        params: Mapping[str, Any] | None = None,
        json: Any = None,
        key: str | None = None,
    ) -> httpx.Response:
        headers = {} if key is None else {"Idempotency-Key": key}
        try:
            response = self._http.request(method, path, params=params, json=json, headers=headers)
        except httpx.TransportError as error:
            raise ServerUnreachable(self.url, _reason(error)) from error
        if not response.is_success:
            raise ApiError.of(response)
        return response

    def _json(self, method: str, path: str, **kwargs: Any) -> dict[str, Any]:
        response = self._request(method, path, **kwargs)
        try:
            data = response.json()
        except ValueError:
            data = None
        if not isinstance(data, dict):
            raise ApiError(
                response.status_code,
                "Not a NanoNav answer",
                f"{method} {response.request.url} did not answer with a JSON object; is "
                f"{self.url} a NanoNav API?",
                instance=path,
            )
        return data

    def _pages(self, path: str, params: Mapping[str, Any], key: str) -> Iterator[dict[str, Any]]:
        """Every item of a listing, following its ``next`` links."""
        page = self._json("GET", path, params=params)
        while True:
            yield from page[key]
            if not page.get("next"):
                return
            page = self._json("GET", page["next"])


def _capped(items: Iterator[_T], limit: int | None) -> Iterator[_T]:
    """The first ``limit`` items, without asking for a page past them."""
    if limit is not None and limit < 1:
        raise ValueError(f"limit must be at least 1, not {limit}")
    for count, item in enumerate(items, 1):
        yield item
        if count == limit:
            return


_A = TypeVar("_A", Job, Study)


def _poll(
    fetch: Callable[[], _A],
    name: str,
    poll_s: float,
    timeout_s: float | None,
    on_progress: Callable[[_A], None] | None,
) -> _A:
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    while True:
        current = fetch()
        if on_progress is not None:
            on_progress(current)
        if current.finished:
            return current
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"{name} is still {current.status} after {timeout_s:g} s")
            time.sleep(min(poll_s, left))
        else:
            time.sleep(poll_s)


def _reason(error: httpx.TransportError) -> str:
    if isinstance(error, httpx.TimeoutException):
        return f"no answer in time ({type(error).__name__})"
    return str(error) or type(error).__name__


def _callback(url: str | None) -> dict[str, str] | None:
    return None if url is None else {"callback_url": url}
