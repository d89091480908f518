"""The reference the engine is measured against: the same physics written the way a first
research script is, one robot and one biomarker point at a time in Python with numpy vectors.

It moves the cells, senses the field and its gradient by summing over every source, finds the
nearest obstacle and cell, picks an epsilon-greedy behaviour from a Q-table, moves, checks
collisions and reach, and applies the eq. 2.7 update, for every robot in turn.
"""

from __future__ import annotations

import math
import time

import numpy as np

from nanonav.scenario import Scenario


class NaiveSwarm:
    """One episode's state, stepped robot by robot."""

    def __init__(self, scenario: Scenario, seed: int = 0) -> None:
        self.s = scenario
        self.rng = np.random.default_rng(seed)
        half = scenario.space.size / 2
        self.half = half
        self.cells = [
            self.rng.uniform(-0.8 * half, 0.8 * half, 3) for _ in range(scenario.cells.count)
        ]
        per_cell = scenario.biomarker.emitters_per_cell
        self.offsets = [
            [self.rng.normal(0, scenario.biomarker.emitter_scatter, 3) for _ in range(per_cell)]
            for _ in self.cells
        ]
        self.robots = [
            self.rng.uniform(-0.95 * half, 0.95 * half, 3) for _ in range(scenario.robots.count)
        ]
        r = scenario.obstacles.radius
        self.obstacles = [
            self.rng.uniform(-half + r, half - r, 3) for _ in range(scenario.obstacles.count)
        ]
        self.q = np.zeros((72, 4))
        self.prev = [-1.0] * len(self.robots)
        self.active = [True] * len(self.robots)

    def sources(self) -> list[np.ndarray]:
        if self.s.biomarker.model == "inverse_square":
            return [c + o for c, offs in zip(self.cells, self.offsets, strict=True) for o in offs]
        return list(self.cells)

    def sense(self, pos: np.ndarray, sources: list[np.ndarray]) -> tuple[float, np.ndarray]:
        b = self.s.biomarker
        c = 0.0
        grad = np.zeros(3)
        for src in sources:
            d = pos - src
            r2 = float(np.dot(d, d))
            if b.model == "gaussian":
                e = b.peak * math.exp(-r2 / (2 * b.spread**2))
                c += e
                grad -= d / b.spread**2 * e
            elif b.model == "inverse_square":
                w = b.peak / b.emitters_per_cell
                s2 = r2 + b.softening**2
                c += w / s2
                grad -= 2 * w * d / s2**2
            else:
                rs = math.sqrt(r2 + b.softening**2)
                e = b.peak * math.exp(-rs / b.decay_length) / rs
                c += e
                grad -= e * (1 / b.decay_length + 1 / rs) * d / rs
        return c, grad

    def step(self) -> int:
        s = self.s
        for j, cell in enumerate(self.cells):
            self.cells[j] = np.clip(
                cell + self.rng.normal(0, s.cells.motion_std, 3), -self.half, self.half
            )
        sources = self.sources()
        moved = 0
        for i, pos in enumerate(self.robots):
            if not self.active[i]:
                continue
            moved += 1
            c, grad = self.sense(pos, sources)
            dists = [float(np.linalg.norm(pos - cell)) for cell in self.cells]
            d_old = min(dists)
            gaps = [float(np.linalg.norm(pos - o)) - s.obstacles.radius for o in self.obstacles]
            gap = min(gaps) if gaps else math.inf
            level = int(c > 0.01) + int(c > 0.1) + int(c > 0.5)
            trend = int(c > self.prev[i])
            obstacle = 2 if gap < s.robots.sensing_radius else 0
            state = ((level * 2 + trend) * 3 + obstacle) * 3
            state += 1 if d_old < s.robots.sensing_radius else 0
            self.prev[i] = c
            if self.rng.random() < 0.1:
                action = int(self.rng.integers(0, 4))
            else:
                action = int(np.argmax(self.q[state]))
            explore = action == 3 or not np.any(grad)
            direction = self.rng.normal(size=3) if explore else grad
            new = pos + s.robots.speed * direction / np.linalg.norm(direction)
            new = np.clip(new, -self.half, self.half)
            reward = 0.0
            if any(np.linalg.norm(new - o) < s.obstacles.radius for o in self.obstacles):
                reward += s.rewards.collision
                new = pos
            d_new = min(float(np.linalg.norm(new - cell)) for cell in self.cells)
            reward += s.rewards.approach * (d_old - d_new)
            if d_new <= s.reach_distance:
                reward += s.rewards.reach
                self.active[i] = False
            target = reward + s.learning.gamma * float(np.max(self.q[state]))
            self.q[state, action] += s.learning.alpha * (target - self.q[state, action])
            self.robots[i] = new
        return moved


def naive_robot_steps_per_second(scenario: Scenario, min_seconds: float = 0.5) -> float:
    """Robot-steps per second of the naive loop, timed over at least ``min_seconds``."""
    episode = 0
    swarm = NaiveSwarm(scenario, episode)
    done = 0
    started = time.perf_counter()
    while True:
        moved = swarm.step()
        done += moved
        elapsed = time.perf_counter() - started
        if elapsed >= min_seconds and done:
            return done / elapsed
        if moved == 0:
            episode += 1
            swarm = NaiveSwarm(scenario, episode)
