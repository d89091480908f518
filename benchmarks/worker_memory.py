"""A worker's resident memory after its first job, and after a job of each other kind.

    python benchmarks/worker_memory.py      # about 15 s once the engine is compiled

One real API process (``nanonav api``) and one ``python -m worker`` over a fresh SQLite file,
as ``make run`` starts them. Once the worker is ready it runs, one after the other: the
README's first job (``paper-single``, seed 7), an active Brownian job
(``tumour-microswimmers``), a sent network's evaluation (a 64x64 MLP, ONNX) and a four-job
study. After each, the worker's resident memory (``VmRSS``) and its peak so far (``VmHWM``)
are read from ``/proc``; a network runs in a sandboxed child of the worker, counted apart.
Target (the issue's): at most 600 MB after the first job.
"""

from __future__ import annotations

import base64
import importlib.util
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import httpx

HERE = Path(__file__).resolve().parent
TARGET_MB = 600.0


def _benchmark(name: str) -> ModuleType:
    """Another benchmark's module, loaded from its path (``service`` is the API's package)."""
    spec = importlib.util.spec_from_file_location(f"{name}_benchmark", HERE / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


api_memory = _benchmark("api_memory")
network_policy = _benchmark("network_policy")


def memory_mb(pid: int) -> tuple[float, float]:
    """Resident memory of ``pid`` now and at its peak, MB."""
    fields = dict(
        line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines()
    )
    return int(fields["VmRSS"].split()[0]) / 1024, int(fields["VmHWM"].split()[0]) / 1024


def network(client: httpx.Client) -> str:
    """A 64x64 MLP sent for the lattice's 'paper-single': its ``policy_from``."""
    from nanonav.engine.observations import action_labels, observation_of
    from nanonav.scenario import Scenario

    scenario = Scenario.model_validate({"preset": "paper-single"})
    columns = list(observation_of(scenario).labels)
    actions = [str(label) for label in action_labels(scenario)]
    model = network_policy.mlp(len(columns), len(actions))

    body = {"onnx": base64.b64encode(model).decode("ascii"), "observation": columns,
            "actions": actions, "name": "mlp 64x64"}  # fmt: skip
    answer = client.post("/policies", json=body, timeout=120)
    if answer.is_error:
        raise RuntimeError(f"POST /policies: {answer.status_code} {answer.text}")
    return str(answer.json()["policy_from"])


def job(client: httpx.Client, scenario: dict[str, Any]) -> None:
    answer = client.post("/jobs", json=scenario)
    answer.raise_for_status()
    api_memory.wait_until(client, f"/jobs/{answer.json()['id']}", "succeeded", timeout_s=600)


def study(client: httpx.Client) -> None:
    body = {"base": {"preset": "paper-single", "learning": {"episodes": 5}},
            "grid": {"robots.count": [1, 2]}, "seeds": [1, 2]}  # fmt: skip
    answer = client.post("/studies", json=body)
    answer.raise_for_status()
    api_memory.wait_until(client, f"/studies/{answer.json()['id']}", "succeeded", timeout_s=600)


def main() -> int:
    print("A worker's resident memory (VmRSS now, VmHWM its peak so far), MB:")
    with (
        api_memory.api_and_worker() as (_, worker, url, workdir),
        httpx.Client(base_url=url, timeout=30) as client,
    ):
        started = time.monotonic()
        while "ready on" not in (workdir / "worker.log").read_text():
            if worker.poll() is not None or time.monotonic() - started > 900:
                raise RuntimeError((workdir / "worker.log").read_text()[-2000:])
            time.sleep(0.2)
        api_memory.wait_until(client, "/healthz", "ok", timeout_s=60)
        now, peak = memory_mb(worker.pid)
        print(f"  {'ready, no job yet':32}{now:8.0f}{peak:8.0f}", flush=True)
        steps: list[tuple[str, Any]] = [
            ("first job: paper-single, seed 7", lambda: job(client, {"preset": "paper-single",
                                                                     "seed": 7})),
            ("tumour-microswimmers", lambda: job(client, {"preset": "tumour-microswimmers"})),
            ("a sent network's evaluation", lambda: job(client, {
                "preset": "paper-single", "learning": {"episodes": 0},
                "policy_from": network(client)})),
            ("a study of four jobs", lambda: study(client)),
        ]  # fmt: skip
        after_first = 0.0
        for label, run in steps:
            run()
            now, peak = memory_mb(worker.pid)
            after_first = after_first or now
            print(f"  {label:32}{now:8.0f}{peak:8.0f}", flush=True)
    verdict = "meets" if after_first <= TARGET_MB else "BELOW"
    print(f"{verdict} target: {after_first:.0f} MB after the first job vs {TARGET_MB:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
