"""Train a policy through the environment, send it to the service, and evaluate it there beside
two fixed policies in the same worlds.

A tabular Q-learner of a few lines learns through ``NanoNavEnv`` on training seeds of its own;
``POST /policies`` keeps its table, and a job whose scenario names it (``policy_from``) runs it
greedily in the evaluation worlds of a seed, the worlds the baselines meet on that seed.

    make run                               # in another terminal: the API and a worker
    python examples/train_and_evaluate.py  # NANONAV_URL names another server
"""

from __future__ import annotations

import sys

import numpy as np

import nanonav.env
from nanonav.client import ApiError, Client, ServerUnreachable

SCENARIO = {"preset": "paper-single"}
EPISODES = 30  # training episodes, each on a seed of its own
TRAINING_SEEDS_FROM = 1000  # seeds no evaluation below uses
EPSILON, ALPHA, GAMMA = 0.2, 0.1, 0.95
EVALUATION_SEED = 7
BASELINES = ("gradient", "rule")


def train(env: nanonav.env.NanoNavEnv) -> np.ndarray:
    """A Q-table learned epsilon-greedily over the engine's own tabular states."""
    q = np.zeros((len(env.state_labels), len(env.action_labels)))
    rng = np.random.default_rng(1)
    for episode in range(EPISODES):
        _, info = env.reset(seed=TRAINING_SEEDS_FROM + episode)
        done = False
        while not done:
            state = info["state"]
            explore = rng.random() < EPSILON
            action = int(rng.integers(q.shape[1])) if explore else int(q[state].argmax())
            _, reward, terminated, truncated, info = env.step(action)
            target = reward if terminated else reward + GAMMA * q[info["state"]].max()
            q[state, action] += ALPHA * (target - q[state, action])
            done = terminated or truncated
    return q


def main() -> int:
    with Client() as api:  # $NANONAV_URL, else http://127.0.0.1:8000
        try:
            next(api.jobs(limit=1), None)  # before training: fails at once if nothing answers
            env = nanonav.env.NanoNavEnv(SCENARIO)
            q = train(env)
            print(
                f"trained {EPISODES} episodes: {len(env.state_labels)} states x "
                f"{len(env.action_labels)} actions"
            )
            policy = api.send_policy(
                env.state_labels, env.action_labels, values=q, name=f"tabular, {EPISODES} episodes"
            )
            print(f"policy {policy.id}: policy_from {policy.policy_from!r}")
            evaluate = {"policy_from": policy.policy_from, "learning": {"episodes": 0}}
            scenarios = {"learned": {**SCENARIO, **evaluate, "seed": EVALUATION_SEED}} | {
                name: {**SCENARIO, "robots": {"policy": name}, "seed": EVALUATION_SEED}
                for name in BASELINES
            }
            jobs = {name: api.submit(scenario).id for name, scenario in scenarios.items()}
            print(f"{'policy':>10} {'job':>4} {'success_rate':>13} {'total_steps':>12}")
            for name, job_id in jobs.items():
                job = api.wait(job_id, timeout_s=300)
                if job.status != "succeeded":
                    print(f"job {job.id} {job.status}: {job.error}", file=sys.stderr)
                    return 1
                summary = api.metrics(job.id)["summary"]
                print(
                    f"{name:>10} {job.id:>4} {summary['success_rate']:>13.3f} "
                    f"{summary['total_steps']:>12.1f}"
                )
        except ServerUnreachable as error:
            print(f"{error}\nstart one with `make run`, or set NANONAV_URL", file=sys.stderr)
            return 1
        except ApiError as error:
            print(error, file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
