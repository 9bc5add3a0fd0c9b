"""The curse of dimensionality: what learning costs as a task's dimension grows, relevant or not.

Two studies, each a CSV under ``OUT/data/`` (``--out``, default ``docs``) and a Markdown table printed, and
``--plot``, which reads the CSVs, draws ``OUT/figures/dimensions.png`` (env steps and cells against d on log axes:
median, the seeds' range as a band, censored runs as open triangles) and ``dimensions_irrelevant.png`` (final
return and cells against k), and fits each agent's median env steps and cells against d with a power law and
an exponential:

* ``--dims``: ``avq/SlabMaze-v0`` at d = 2, 3, 4, 6, 8 (move 0.1, one slab per axis, ``layout_seed`` d). Each
  agent learns in chunks of episodes (1, 2, 4, ... up to 200, as ``benchmarks/scaling.py``'s ``learn_until``);
  after every chunk its greedy policy walks from 50 fixed starts (``start_positions(50, seed=1)``, each walk
  up to the env's step limit). A run reaches when 90% of the walks end in the goal; one that does not
  within the budget of env steps (default 200k, the same for every agent) is censored, shown ``>``. Per run:
  the env steps then, the cells (states for ``grid-ps``, tiles in use for ``tiles``), the last greedy
  success, the wall seconds and the env steps per second of learning. The AVQ agents' cells are not capped
  (``max_cells`` 1,000,000), so that their number is measured; ``tiles`` hashes into 2^18 weights instead of
  4,096 (8 tilings of 8^d tiles); ``grid-ps`` has one bin per move on every axis, ``ceil(1 / move)^d`` bins,
  and is skipped (a note printed) where that is more than 2,000,000 (d = 8). SlabMaze has no entry of its own
  in the agents' defaults: ``avq`` is the planning agent with its general ones; ``avq-axis`` is ``avq`` with
  ``collision_cut`` instead of the paper's growth on collisions and ``axis_share`` 0.8; ``avq-known1`` is ``avq``
  with ``known_after`` 1, as the mazes' entries and ``grid-ps`` have it; ``avq-goal10`` is ``avq`` with ``v_opt``
  10, the goal's reward, as they have it too; ``avq-unsettled`` is ``avq`` with ``outcome_split`` "unsettled".
  With ``--start fixed`` (parti-game's protocol) every episode starts at the maze's fixed start near the corner
  ``(0, ..., 0)``, and a run reaches when the greedy walk from there ends in the goal:
  ``OUT/data/dimensions_fixed.csv``, drawn in no figure. With ``--shaped`` every agent's rewards are shaped by a
  potential, the negative of the goal's distance in moves walls aside (``avq.envs.PotentialShaping``,
  ``SlabMaze.goal_distance``): the agents are told where the goal is, as parti-game is;
  ``OUT/data/dimensions_shaped.csv`` or ``dimensions_fixed_shaped.csv``.
* ``--irrelevant``: MountainCar-v0 and CartPole-v1 with k = 0, 2, 4, 8 noise dimensions appended
  (``avq.envs.IrrelevantDims``), 300 episodes. Every k gets the agent's defaults for the task itself (which
  ``make_agent`` would replace by the general ones on a wrapped task), per-dimension settings extended over
  the new dimensions (metric weight 1, bounds [0, 1]); the cells keep their budget (2,048 for the AVQ
  agents). Per run: the final return (mean of the last 50 episodes), the episodes and env steps until the
  mean of 20 consecutive episodes reaches Gymnasium's reward threshold (MountainCar -110, CartPole 475), cells,
  wall seconds.

``--lattice`` prints, for each d (2, 3, 4, 6; 8 has 10^8 lattice points), what an explorer of the lattice of
moves faces from the fixed start: the goal's distance in moves (``SlabMaze.shortest_steps``), and the lattice
points nearer than that distance less the goal's reward (``SlabMaze.lattice_distances``). With untried decisions
worth 0 and -1 a move, R-max's agent on that lattice (``grid-ps``) values every untried decision there above the
path to the goal, so it tries them all before it heads for the goal; no learning, a few seconds. The last column: the
points whose moves from the start plus the goal's distance walls aside (``SlabMaze.goal_distance``) are at most
that distance, the only points A* would expand before it reaches the goal; an explorer told the goal's distance
(``--shaped``) ranks untried decisions by that sum, as A* does, though one that plans from where it stands may
stray beyond them. And the most of the goal's places on the lattice that any explorer not told where the goal is
can find within ``--budget`` env steps (200,000): until its first +10 it sees the same wherever the goal is, and
it stands on at most one point more than its moves.

``--agents dqn`` adds Stable-Baselines3's DQN with RL Baselines3 Zoo's hyper-parameters (:data:`ZOO_DQN`),
imported only then (``pip install stable-baselines3 torch``; not an extra of avq). Its cells are the
Q-network's parameters. Rows of agents not run are kept from the CSV, so that an agent can be added later.

    python benchmarks/dimensions.py --dims                      # docs/data/dimensions.csv
    python benchmarks/dimensions.py --irrelevant                # docs/data/dimensions_irrelevant.csv
    python benchmarks/dimensions.py --plot                      # docs/figures/dimensions*.png, the fits
    python benchmarks/dimensions.py --dims --agents dqn         # add DQN's rows
    python benchmarks/dimensions.py --dims --start fixed        # docs/data/dimensions_fixed.csv
    python benchmarks/dimensions.py --dims --start fixed --shaped --budget 1000000   # dimensions_fixed_shaped.csv
    python benchmarks/dimensions.py --lattice                   # the explorer's task at each d: a table
    python benchmarks/dimensions.py --quick --dims --irrelevant --plot --jobs 1 --out /tmp/dims   # a check
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from joblib import Parallel, delayed

import avq
from avq.agents.registry import agent_defaults
from avq.envs import IrrelevantDims, PotentialShaping, SlabMaze
from avq.envs.grid_maze import GOAL_REWARD, MOVE_REWARD
from avq.envs.slab_geometry import slab_move
from avq.envs.slab_maze import MAX_LATTICE

DIMS, QUICK_DIMS = (2, 3, 4, 6, 8), (2, 3)
KS, QUICK_KS = (0, 2, 4, 8), (0, 2)
MOVE, TARGET, EVAL_STARTS, EVAL_SEED = 0.1, 0.9, 50, 1
MAX_BINS = 2_000_000
UNCAPPED = {"max_cells": 1_000_000}
DIMS_AGENTS = {"avq": UNCAPPED, "avq-sarsa": UNCAPPED, "tiles": {"iht_size": 1 << 18}, "grid-ps": {}}
#: ``avq`` with the cuts across one axis instead of the paper's growth on collisions (not its defaults: on classic
#: control the outcome split across one axis costs; docs/results/dimensions.md).
DIMS_AGENTS["avq-axis"] = {**UNCAPPED, "collision_growth": False, "collision_cut": True, "axis_share": 0.8}
#: ``avq`` with a decision known after one try, as the mazes' entries and ``grid-ps`` have it (a maze's moves have
#: one outcome each; on classic control it did not hold up: docs/results/dimensions.md#more-probes).
DIMS_AGENTS["avq-known1"] = {**UNCAPPED, "known_after": 1}
#: ``avq`` with an untried decision worth the goal's reward (10), as the mazes' entries and ``grid-ps`` have it:
#: R-max's bound on the untold maze, where that reward comes once an episode. ``v_opt`` "auto" is 0 once a reward
#: below 0 has been seen (here from the first move); a fixed ``v_opt`` also drops "auto"'s ceiling on planned values.
DIMS_AGENTS["avq-goal10"] = {**UNCAPPED, "v_opt": 10.0}
#: ``avq`` whose outcome split also compares outcomes that end in cells not settled whose values owe nothing to
#: optimism (``outcome_split`` "unsettled"): beside the goal, where untried decisions are worth 0 and never tried,
#: cells never settle and the default's split never compares them (docs/results/dimensions.md#unsettled).
DIMS_AGENTS["avq-unsettled"] = {**UNCAPPED, "outcome_split": "unsettled"}
#: The registered agent of each variant that is not one itself.
REGISTERED = {"avq-axis": "avq", "avq-known1": "avq", "avq-goal10": "avq", "avq-unsettled": "avq"}
#: ``--dims``' agents when ``--agents`` is not given: the study's (the first section's CSV and figure); the other
#: variants of :data:`DIMS_AGENTS` run when named.
DIMS_STUDY = ("avq", "avq-sarsa", "tiles", "grid-ps", "avq-axis")
IRRELEVANT_AGENTS = ("avq", "avq-sarsa", "tiles")
TASKS = ("MountainCar-v0", "CartPole-v1")
#: CartPole's velocities are unbounded; tiles cuts a box (benchmarks/compare.py's).
CARTPOLE_BOUNDS = [[-2.4, 2.4], [-3.0, 3.0], [-0.21, 0.21], [-3.5, 3.5]]
WINDOW, TAIL = 20, 50
DIMS_FIELDS = (
    "agent", "d", "states", "seed", "reached", "env_steps", "budget", "cells", "success", "wall_s", "steps_per_s",
)  # fmt: skip
IRR_FIELDS = (
    "task", "agent", "k", "seed", "episodes", "final_return", "threshold", "episodes_to_threshold",
    "steps_to_threshold", "env_steps", "cells", "wall_s",
)  # fmt: skip

#: RL Baselines3 Zoo's DQN settings, DLR-RM/rl-baselines3-zoo hyperparams/dqn.yml (commit 22e3ff2, 2026-04-23;
#: the file last changed in eec15dc): n_timesteps, then DQN's arguments; net_arch is its policy_kwargs.
_ACROBOT = dict(
    n_timesteps=100_000, learning_rate=6.3e-4, batch_size=128, buffer_size=50_000, learning_starts=0, gamma=0.99,
    target_update_interval=250, train_freq=4, gradient_steps=-1, exploration_fraction=0.12,
    exploration_final_eps=0.1, net_arch=[256, 256],
)  # fmt: skip
ZOO_DQN = {
    "CartPole-v1": dict(
        n_timesteps=50_000, learning_rate=2.3e-3, batch_size=64, buffer_size=100_000, learning_starts=1000,
        gamma=0.99, target_update_interval=10, train_freq=256, gradient_steps=128, exploration_fraction=0.16,
        exploration_final_eps=0.04, net_arch=[256, 256],
    ),
    "MountainCar-v0": dict(
        n_timesteps=120_000, learning_rate=4e-3, batch_size=128, buffer_size=10_000, learning_starts=1000,
        gamma=0.98, target_update_interval=600, train_freq=16, gradient_steps=8, exploration_fraction=0.2,
        exploration_final_eps=0.07, net_arch=[256, 256],
    ),
    "Acrobot-v1": _ACROBOT,
    "LunarLander-v3": _ACROBOT,  # (the zoo's two entries are the same)
    # SlabMaze has no entry; Acrobot's is the zoo's nearest task: a goal to reach, -1 a step until then.
    "avq/SlabMaze-v0": _ACROBOT,
}  # fmt: skip


def require_sb3() -> None:
    """Stop, saying what to install, where Stable-Baselines3 or PyTorch is missing (agent dqn only)."""
    try:
        import stable_baselines3  # noqa: F401
        import torch  # noqa: F401
    except ImportError as exc:
        raise SystemExit(
            f"agent dqn needs Stable-Baselines3 and PyTorch ({exc}): pip install stable-baselines3 torch"
        ) from None


class ZooDQN:
    """Stable-Baselines3's DQN with :data:`ZOO_DQN`'s settings for ``task``, behind the calls made here.

    The zoo anneals ε over ``exploration_fraction`` of its ``n_timesteps``; SB3 anneals it over that fraction of
    the steps a ``learn`` call aims at, here always ``horizon`` (each call asks for the steps left until then),
    so the fraction is rescaled: the zoo's schedule in env steps. ``n_cells``: the Q-network's parameters.
    """

    def __init__(self, env: gym.Env, task: str, seed: int, horizon: int) -> None:
        require_sb3()
        import torch
        from stable_baselines3 import DQN
        from stable_baselines3.common.monitor import Monitor

        torch.set_num_threads(1)  # (one process a core: --jobs runs in parallel)
        params = dict(ZOO_DQN[task])
        zoo_steps, arch = params.pop("n_timesteps"), params.pop("net_arch")
        params["exploration_fraction"] = min(1.0, params["exploration_fraction"] * zoo_steps / horizon)
        self.env, self.horizon = Monitor(env), horizon
        self.model = DQN("MlpPolicy", self.env, policy_kwargs={"net_arch": arch}, seed=seed, verbose=0, **params)

    def learn_checked(self, every: int, check) -> None:
        """Learn up to the horizon in one call of SB3's ``learn``, calling ``check(env_steps)`` after every ``every``
        env steps and at the horizon (as SB3's EvalCallback does: no training step is lost at a check, as one
        would be at the end of a ``learn`` call stopped between two of its training rounds)."""
        from stable_baselines3.common.callbacks import BaseCallback

        horizon = self.horizon

        class Checks(BaseCallback):
            def _on_step(self) -> bool:
                if self.num_timesteps % every == 0 or self.num_timesteps == horizon:
                    check(self.num_timesteps)
                return True

        self.model.learn(self.horizon, callback=Checks())

    def learn_episodes(self, episodes: int) -> None:
        from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

        if self.horizon > self.num_timesteps:
            stop = StopTrainingOnMaxEpisodes(episodes)
            self.model.learn(self.horizon - self.num_timesteps, callback=stop, reset_num_timesteps=False)

    def predict(self, obs: np.ndarray, deterministic: bool = True):
        return self.model.predict(obs, deterministic=deterministic)

    @property
    def num_timesteps(self) -> int:
        return int(self.model.num_timesteps)

    @property
    def n_cells(self) -> int:
        return sum(p.numel() for p in self.model.q_net.parameters())

    def episode_history(self) -> dict[str, np.ndarray]:
        return {"return": np.array(self.env.get_episode_rewards()), "steps": np.array(self.env.get_episode_lengths())}


def learn_episodes(agent, episodes: int, budget: int) -> None:
    """``episodes`` more episodes, fewer where ``budget`` env steps in all are spent first (checked at the end of
    an episode for avq's agents: a run may pass the budget by the rest of one episode)."""
    if isinstance(agent, ZooDQN):
        agent.learn_episodes(episodes)  # (its horizon is the budget)
    else:
        agent.learn(total_episodes=episodes, callback=lambda a, _: a.num_timesteps < budget)


def greedy_success(agent, maze, starts: np.ndarray) -> float:
    """The fraction of ``starts`` from which the greedy policy reaches the goal of a SlabMaze (slip 0) within its
    step limit: the walks in lockstep, one batched ``predict`` a step, each move the maze's own compiled one (the
    same as stepping the env from ``reset(options={"start": x})``)."""
    pos, alive = starts.astype(np.float64), np.arange(len(starts))
    slabs, goal_low = maze.slab_arrays, 1.0 - maze.goal_size
    for _ in range(maze.max_steps):
        if alive.size == 0:
            break
        actions, _ = agent.predict(pos[alive].astype(np.float32), deterministic=True)
        done = np.zeros(alive.size, dtype=bool)
        for j, (k, a) in enumerate(zip(alive, np.asarray(actions).reshape(-1).tolist())):
            done[j] = slab_move(pos[k], a >> 1, -maze.move if a & 1 else maze.move, slabs, goal_low)[1]
        alive = alive[~done]
    return 1.0 - alive.size / len(starts)


def learn_until(agent, success_of, budget: int, target: float, max_chunk: int = 200) -> tuple[bool, float, float]:
    """Learn in chunks of episodes (1, 2, 4, ... up to ``max_chunk``) until ``success_of(agent)`` reaches ``target``
    or ``budget`` env steps are spent: ``(reached, last success, seconds spent learning)``."""
    chunk, learning, success = 1, 0.0, 0.0
    while agent.num_timesteps < budget:
        t0 = time.perf_counter()
        learn_episodes(agent, chunk, budget)
        learning += time.perf_counter() - t0
        success = success_of(agent)
        if success >= target:
            return True, success, learning
        chunk = min(2 * chunk, max_chunk)
    return False, success, learning


def grid_bins(d: int) -> int:
    return math.ceil(1.0 / MOVE - 1e-9) ** d


def dims_run(name: str, d: int, seed: int, budget: int, start: str = "random", shaped: bool = False) -> dict:
    """One agent on the slab maze of dimension ``d``; with ``shaped``, its rewards shaped by the negative of the
    goal's distance in moves (:class:`avq.envs.PotentialShaping`, ``SlabMaze.goal_distance``)."""
    t0 = time.perf_counter()
    env = gym.make("avq/SlabMaze-v0", dims=d, move=MOVE, layout_seed=d, start=start)
    maze = env.unwrapped
    if shaped:
        env = PotentialShaping(env, lambda obs: -maze.goal_distance(obs))
    if name == "dqn":
        agent = ZooDQN(env, "avq/SlabMaze-v0", seed, budget)
    else:
        overrides = dict(DIMS_AGENTS[name])
        if name == "grid-ps":
            overrides.update(bins=math.ceil(1.0 / MOVE - 1e-9), max_states=grid_bins(d))
        agent = avq.make_agent(REGISTERED.get(name, name), env, seed=seed, **overrides)
    if start == "fixed":  # (the one walk of a deterministic maze: it reaches the goal or not)
        starts, target = maze.reset()[0][None, :], 1.0
    else:
        starts, target = maze.start_positions(EVAL_STARTS, seed=EVAL_SEED), TARGET
    reached, success, learning = learn_until(agent, lambda a: greedy_success(a, maze, starts), budget, target)
    steps = agent.num_timesteps
    return dict(
        agent=name, d=d, states=maze.full_resolution_states, seed=seed, reached=reached, env_steps=steps,
        budget=budget, cells=int(agent.n_cells), success=round(success, 3),
        wall_s=round(time.perf_counter() - t0, 2), steps_per_s=round(steps / max(learning, 1e-9)),
    )  # fmt: skip


def task_params(name: str, task: str, k: int) -> dict:
    """``name``'s defaults on ``task`` itself, per-dimension settings extended over ``k`` more dimensions."""
    params = agent_defaults(name, task)
    if name == "tiles" and task.startswith("CartPole"):
        params["obs_bounds"] = CARTPOLE_BOUNDS
    return extend_dims(params, k)


def extend_dims(params: dict, k: int) -> dict:
    """``params`` with its per-dimension settings (``scale_factor``, ``obs_bounds``) extended over ``k`` appended
    dimensions of :class:`IrrelevantDims`: weight 1, bounds [0, 1]."""
    params = dict(params)
    if isinstance(params.get("scale_factor"), (list, tuple)):
        params["scale_factor"] = [*params["scale_factor"], *[1.0] * k]
    if params.get("obs_bounds") is not None:
        params["obs_bounds"] = [*params["obs_bounds"], *[[0.0, 1.0]] * k]
    return params


def to_threshold(
    returns: np.ndarray, steps: np.ndarray, threshold: float, window: int = WINDOW
) -> tuple[int | None, int | None]:
    """Episodes and env steps up to the end of the first ``window`` consecutive episodes whose mean reaches
    ``threshold``; ``(None, None)`` if none does."""
    if len(returns) < window:
        return None, None
    c = np.cumsum(np.insert(np.asarray(returns, float), 0, 0.0))
    hit = np.flatnonzero((c[window:] - c[:-window]) / window >= threshold)
    return (None, None) if hit.size == 0 else (int(hit[0] + window), int(np.sum(steps[: hit[0] + window])))


def irrelevant_run(name: str, task: str, k: int, seed: int, episodes: int, kind: str = "noise") -> dict:
    t0 = time.perf_counter()
    env = IrrelevantDims(gym.make(task), k, kind=kind)
    if name == "dqn":
        agent = ZooDQN(env, task, seed, episodes * gym.spec(task).max_episode_steps)
        agent.learn_episodes(episodes)
    else:
        agent = avq.make_agent(name, env, seed=seed, **task_params(name, task, k))
        agent.learn(total_episodes=episodes)
    hist = agent.episode_history()
    returns, steps = hist["return"][:episodes], hist["steps"][:episodes]
    threshold = gym.spec(task).reward_threshold
    n, s = to_threshold(returns, steps, threshold)
    return dict(
        task=task, agent=name, k=k, seed=seed, episodes=len(returns),
        final_return=round(float(np.mean(returns[-min(TAIL, max(1, episodes // 2)) :])), 2), threshold=threshold,
        episodes_to_threshold=n, steps_to_threshold=s, env_steps=int(np.sum(steps)), cells=int(agent.n_cells),
        wall_s=round(time.perf_counter() - t0, 2),
    )  # fmt: skip


# -- files and tables ------------------------------------------------------------------------------------------
def read_csv(path: Path) -> list[dict]:
    """The rows of a CSV written here, numbers as numbers (empty: None)."""
    if not path.exists():
        return []
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for key, v in r.items():
            if key not in ("agent", "task"):
                r[key] = _value(v)
    return rows


def _value(text: str):
    """A CSV field as a number, a bool or None (empty); a word (``v_opt``'s "auto") as it is."""
    if text in ("", "True", "False"):
        return None if text == "" else text == "True"
    try:
        return (float if "." in text or "e" in text.lower() else int)(text)
    except ValueError:
        return text


def finished(n_jobs: int, jobs: list) -> list[dict]:
    """Run ``jobs`` on ``n_jobs`` processes, printing a line as each run is returned, in order (runs at d = 6 take minutes)."""
    rows = []
    for r in Parallel(n_jobs, return_as="generator")(jobs):
        rows.append(r)
        shown = {k: r[k] for k in ("agent", "task", "d", "k", "seed", "env_steps", "cells", "wall_s") if k in r}
        print(f"  [{len(rows)}/{len(jobs)}] " + ", ".join(f"{k} {v}" for k, v in shown.items()), flush=True)
    return rows


def write_csv(path: Path, fields: tuple[str, ...], rows: list[dict], match: tuple[str, ...]) -> list[dict]:
    """Write ``rows`` with the file's rows kept where no new row has the same ``match`` fields (an agent at a d, say:
    so that agents and dimensions can be added one at a time); return them all."""

    def key(r: dict) -> tuple[str, ...]:  # (an empty field reads back as None)
        return tuple("" if r[k] is None else str(r[k]) for k in match)

    ran = {key(r) for r in rows}
    old = [r for r in read_csv(path) if key(r) not in ran]  # (read back: numbers)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(old + rows)
    return read_csv(path)


def spread(values, fmt: str = "{:,.0f}") -> str:
    v = np.asarray(values, float)
    return f"{fmt.format(np.median(v))} [{fmt.format(v.min())} to {fmt.format(v.max())}]"


def censored_median(steps: list[float], reached: list[bool]) -> tuple[float, bool]:
    """The median with censored runs counted as more than any (their own steps where the median falls among them):
    ``(value, censored)``."""
    order = np.median(np.where(reached, steps, np.inf))
    return (float(order), False) if np.isfinite(order) else (float(np.median(steps)), True)


def dims_table(rows: list[dict], level: str = "90%") -> None:
    print(
        f"| d | states | agent | reached {level} | env steps to {level}: median [range] | cells | last success | steps/s "
        "| s/run |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for d in sorted({r["d"] for r in rows}):
        for name in dict.fromkeys(r["agent"] for r in rows):
            rs = [r for r in rows if r["d"] == d and r["agent"] == name]
            if not rs:
                continue
            st, ok = [r["env_steps"] for r in rs], [r["reached"] for r in rs]
            med, cens = censored_median(st, ok)
            print(
                f"| {d:.0f} | {rs[0]['states']:,.0f} | {name} | {sum(ok)} of {len(rs)} | {'>' * cens}{med:,.0f} "
                f"[{min(st):,.0f} to {max(st):,.0f}] | {spread([r['cells'] for r in rs])} | "
                f"{np.median([r['success'] for r in rs]):.0%} | {np.median([r['steps_per_s'] for r in rs]):,.0f} | "
                f"{np.median([r['wall_s'] for r in rs]):.1f} |"
            )


def irrelevant_table(rows: list[dict]) -> None:
    print(
        "| task | k | agent | final return | episodes to threshold, runs there | env steps to threshold | cells | s/run |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for task in dict.fromkeys(r["task"] for r in rows):
        for k in sorted({r["k"] for r in rows if r["task"] == task}):
            for name in dict.fromkeys(r["agent"] for r in rows):
                rs = [r for r in rows if r["task"] == task and r["k"] == k and r["agent"] == name]
                if not rs:
                    continue
                ok = [r["episodes_to_threshold"] is not None for r in rs]
                ep, _ = censored_median([r["episodes_to_threshold"] or r["episodes"] for r in rs], ok)
                st, cens = censored_median([r["steps_to_threshold"] or r["env_steps"] for r in rs], ok)
                print(
                    f"| {task} | {k:.0f} | {name} | {spread([r['final_return'] for r in rs], '{:.1f}')} | "
                    f"{'>' * cens}{ep:.0f}, {sum(ok)}/{len(rs)} | {'>' * cens}{st:,.0f} | "
                    f"{spread([r['cells'] for r in rs])} | {np.median([r['wall_s'] for r in rs]):.1f} |"
                )


# -- the figures and the fits ------------------------------------------------------------------------------------
def growth_fits(rows: list[dict]) -> None:
    """Fit each agent's median env steps and cells against d: a power law ``a d^b`` and an exponential ``a c^d``,
    both straight lines on the logarithm of the value (the better: the smaller residual there)."""
    print("\n| agent | quantity | power law: exponent b, R^2 | exponential: factor c a dimension, R^2 | better |")
    print("|---|---|---|---|---|")
    for name in dict.fromkeys(r["agent"] for r in rows):
        ds = sorted({r["d"] for r in rows if r["agent"] == name})
        if len(ds) < 2:
            continue
        for what in ("env_steps", "cells"):
            y, cens = [], False
            for d in ds:
                rs = [r for r in rows if r["agent"] == name and r["d"] == d]
                if what == "env_steps":
                    v, c = censored_median([r["env_steps"] for r in rs], [r["reached"] for r in rs])
                    y.append(v)
                    cens |= c
                else:
                    y.append(float(np.median([r["cells"] for r in rs])))
            logy, x = np.log(y), np.asarray(ds, float)
            fits = {}
            for label, xs in (("power", np.log(x)), ("exp", x)):
                slope, icpt = np.polyfit(xs, logy, 1)
                ss = float(np.sum((logy - (slope * xs + icpt)) ** 2))
                total = float(np.sum((logy - logy.mean()) ** 2))
                fits[label] = (slope, 1.0 - ss / total if total > 0 else 1.0, ss)
            better = "power law" if fits["power"][2] < fits["exp"][2] else "exponential"
            note = " (censored medians: lower bounds)" if cens else ""
            if len(ds) == 2:
                better, note = "-", note + " (2 values of d: both fit exactly)"
            print(
                f"| {name} | {what}{note} | {fits['power'][0]:.2f}, {fits['power'][1]:.3f} | "
                f"{math.exp(fits['exp'][0]):.2f}, {fits['exp'][1]:.3f} | {better} |"
            )


def plot(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    figures = out / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    rows = read_csv(out / "data" / "dimensions.csv")
    if rows:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        ds = sorted({r["d"] for r in rows})
        for i, name in enumerate(dict.fromkeys(r["agent"] for r in rows)):
            color = f"C{i}"
            at = [d for d in ds if any(r["agent"] == name and r["d"] == d for r in rows)]
            for ax, what in zip(axes, ("env_steps", "cells")):
                per = [[r for r in rows if r["agent"] == name and r["d"] == d] for d in at]
                vals = [[r[what] for r in rs] for rs in per]
                ax.plot(at, [np.median(v) for v in vals], "o-", color=color, label=name)
                ax.fill_between(at, [min(v) for v in vals], [max(v) for v in vals], color=color, alpha=0.15)
                cut = [(r["d"], r["env_steps"]) for rs in per for r in rs if not r["reached"]]
                if what == "env_steps" and cut:
                    ax.plot(*zip(*cut), "^", color=color, mfc="none", ms=8)
        states = {r["d"]: r["states"] for r in rows}
        axes[1].plot(ds, [states[d] for d in ds], "k:", label="one state per move")
        labels = ("env steps to 90% greedy success (^: not reached)", "cells, states or tiles then")
        for ax, label in zip(axes, labels):
            ax.set(xscale="log", yscale="log", xlabel="dimension d", ylabel=label)
            ax.set_xticks(ds)
            ax.xaxis.set_major_formatter(ScalarFormatter())
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.grid(alpha=0.3)
        axes[1].legend(fontsize=8)
        seeds = len({r["seed"] for r in rows})
        fig.suptitle(f"SlabMaze, move {MOVE}: median and range over {seeds} seeds", fontsize=10)
        fig.tight_layout()
        fig.savefig(figures / "dimensions.png", dpi=130)
        print(f"wrote {figures / 'dimensions.png'}")
        growth_fits(rows)
    rows = read_csv(out / "data" / "dimensions_irrelevant.csv")
    if rows:
        tasks = list(dict.fromkeys(r["task"] for r in rows))
        fig, axes = plt.subplots(len(tasks), 2, figsize=(10, 3.6 * len(tasks)), squeeze=False)
        for (ax_r, ax_c), task in zip(axes, tasks):
            ks = sorted({r["k"] for r in rows if r["task"] == task})
            for i, name in enumerate(dict.fromkeys(r["agent"] for r in rows)):
                per = [[r for r in rows if r["task"] == task and r["k"] == k and r["agent"] == name] for k in ks]
                at = [k for k, rs in zip(ks, per) if rs]
                for ax, what in ((ax_r, "final_return"), (ax_c, "cells")):
                    vals = [[r[what] for r in rs] for rs in per if rs]
                    ax.plot(at, [np.median(v) for v in vals], "o-", color=f"C{i}", label=name)
                    ax.fill_between(at, [min(v) for v in vals], [max(v) for v in vals], color=f"C{i}", alpha=0.15)
            ax_r.axhline(rows[[r["task"] for r in rows].index(task)]["threshold"], color="k", ls=":", lw=1)
            ax_r.set(xlabel="irrelevant dimensions k", ylabel=f"{task}: final return (threshold dotted)")
            ax_c.set(xlabel="irrelevant dimensions k", ylabel="cells, tiles or weights (dqn) at the end", yscale="log")
            for ax in (ax_r, ax_c):
                ax.set_xticks(ks)
                ax.grid(alpha=0.3)
        axes[0][0].legend(fontsize=8)
        fig.suptitle("Noise dimensions appended (IrrelevantDims): median and range over seeds", fontsize=10)
        fig.tight_layout()
        fig.savefig(figures / "dimensions_irrelevant.png", dpi=130)
        print(f"wrote {figures / 'dimensions_irrelevant.png'}")


def lattice_table(ds: list[int], budget: int) -> None:
    """The lattice of moves through the fixed start at each d: the goal's distance, the points nearer, the
    points an explorer told the goal's distance may try before it reaches the goal, and the most of the goal's
    places on the lattice that any explorer not told where it is can find within ``budget`` env steps."""
    print(
        "| d | lattice points | moves to the goal, D (without slabs) | points fewer than D - 11 moves away "
        f"| told the goal's distance h: points with moves + h <= D | places found within {budget:,}, at most |"
    )
    print("|---|---|---|---|---|---|")
    for d in ds:
        maze = SlabMaze(dims=d, move=MOVE, layout_seed=d, start="fixed")
        dist, points = maze.lattice_distances()
        steps = maze.shortest_steps()
        free = SlabMaze(dims=d, walls=[], move=MOVE, start="fixed").shortest_steps()
        path = (steps - 1) * MOVE_REWARD + GOAL_REWARD  # (the path's return; an untried decision is worth 0)
        near = int(((dist >= 0) & (dist * MOVE_REWARD > path)).sum())
        grid = np.stack(np.meshgrid(*points, indexing="ij"), axis=-1).reshape(-1, d)
        h = np.asarray(maze.goal_distance(grid)).reshape(dist.shape)
        ahead = int(((dist >= 0) & (dist + h <= steps)).sum())
        # Until its first +10 an explorer sees the same whatever point is the goal, and it stands on at most
        # budget + 1 points in budget moves: of the goal's places it can find at most that many.
        found = min(1.0, (budget + 1) / int((dist >= 0).sum()))
        print(
            f"| {d} | {dist.size:,} | {steps} ({free}) | {near:,} ({near / dist.size:.0%}) "
            f"| {ahead:,} ({ahead / dist.size:.0%}) | {found:.0%} |"
        )


def seeds_of(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("--dims", action="store_true", help="SlabMaze at growing d")
    ap.add_argument("--irrelevant", action="store_true", help="MountainCar and CartPole with noise dimensions")
    ap.add_argument("--plot", action="store_true", help="figures from OUT/data's CSVs, and the fits")
    ap.add_argument("--lattice", action="store_true", help="the lattice of moves an explorer faces at each d")
    ap.add_argument("--quick", action="store_true", help="d = 2, 3; k = 0, 2; seeds 0-1; small budgets")
    ap.add_argument("--agents", default=None, help="comma-separated (default: the study's; dqn: SB3's DQN)")
    ap.add_argument("--seeds", default=None, help="a range, as 0-4 (the default; --quick 0-1)")
    ap.add_argument("--d", default=None, help="comma-separated dimensions instead of 2,3,4,6,8")
    ap.add_argument("--k", default=None, help="comma-separated irrelevant dimensions instead of 0,2,4,8")
    ap.add_argument(
        "--budget",
        type=int,
        default=None,
        help="--dims: env steps a run (200,000; --quick 20,000); --lattice: the explorer's, for the last column",
    )
    ap.add_argument("--episodes", type=int, default=None, help="--irrelevant: episodes a run (300; --quick 60)")
    ap.add_argument("--kind", choices=("noise", "walk"), default="noise", help="--irrelevant: IrrelevantDims' kind")
    ap.add_argument("--start", choices=("random", "fixed"), default="random", help="--dims: SlabMaze's start")
    ap.add_argument("--shaped", action="store_true", help="--dims: rewards shaped by the goal's distance")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs", help="CSVs in OUT/data, figures in OUT/figures (default docs)")
    args = ap.parse_args()
    if not (args.dims or args.irrelevant or args.plot or args.lattice):
        ap.error("choose --dims, --irrelevant, --plot and/or --lattice")
    out = Path(args.out)
    if args.quick and out.resolve() == (Path(__file__).resolve().parents[1] / "docs"):
        ap.error("--quick is a check: write it elsewhere than docs (e.g. --out /tmp/dims)")
    seeds = seeds_of(args.seeds or ("0-1" if args.quick else "0-4"))
    for study, default, known in (
        ("dims", DIMS_STUDY, DIMS_AGENTS),
        ("irrelevant", IRRELEVANT_AGENTS, IRRELEVANT_AGENTS),
    ):
        if not getattr(args, study):
            continue
        names = args.agents.split(",") if args.agents else list(default)
        if unknown := [n for n in names if n not in (*known, "dqn")]:
            ap.error(f"--agents {','.join(unknown)}: choose from {', '.join(known)}, dqn")
        if "dqn" in names:
            require_sb3()
        t0 = time.perf_counter()
        if study == "dims":
            ds = [int(v) for v in args.d.split(",")] if args.d else QUICK_DIMS if args.quick else DIMS
            budget = args.budget or (20_000 if args.quick else 200_000)
            for name, d in [(n, d) for n in names for d in ds if n == "grid-ps" and grid_bins(d) > MAX_BINS]:
                print(f"note: {name} skipped at d = {d}: {grid_bins(d):.0e} bins (one per move a dimension)")
            jobs = [
                delayed(dims_run)(n, d, s, budget, args.start, args.shaped)
                for d in ds
                for n in names
                for s in seeds
                if n != "grid-ps" or grid_bins(d) <= MAX_BINS
            ]
            what = "SlabMaze" + (" shaped by the goal's distance" if args.shaped else "")
            print(f"{len(jobs)} runs: {what} d {ds}, seeds {seeds}, budget {budget:,} env steps")
            csv_name = "dimensions" + ("_fixed" if args.start == "fixed" else "") + ("_shaped" if args.shaped else "")
            csv_name += ".csv"
            rows = write_csv(out / "data" / csv_name, DIMS_FIELDS, finished(args.jobs, jobs), ("agent", "d"))
            dims_table(rows, "90%" if args.start == "random" else "the goal")
        else:
            ks = [int(v) for v in args.k.split(",")] if args.k else QUICK_KS if args.quick else KS
            episodes = args.episodes or (60 if args.quick else 300)
            jobs = [
                delayed(irrelevant_run)(n, t, k, s, episodes, args.kind)
                for t in TASKS
                for k in ks
                for n in names
                for s in seeds
            ]
            print(f"{len(jobs)} runs: {', '.join(TASKS)}, k {ks} ({args.kind}), seeds {seeds}, {episodes} episodes")
            new = finished(args.jobs, jobs)
            csv_name = "dimensions_irrelevant.csv" if args.kind == "noise" else f"dimensions_irrelevant_{args.kind}.csv"
            rows = write_csv(out / "data" / csv_name, IRR_FIELDS, new, ("task", "agent", "k"))
            irrelevant_table(rows)
        print(f"({time.perf_counter() - t0:.0f} s with {args.jobs} jobs)\n")
    if args.lattice:
        ds = [int(v) for v in args.d.split(",")] if args.d else [d for d in DIMS if grid_bins(d) <= MAX_LATTICE]
        if too_large := [d for d in ds if grid_bins(d) > MAX_LATTICE]:
            ap.error(
                f"--lattice --d {args.d}: d = {too_large} has more than {MAX_LATTICE:,} lattice points; give d up to 6"
            )
        lattice_table(ds, args.budget or 200_000)
    if args.plot:
        plot(out)


if __name__ == "__main__":
    main()
