"""How many environment steps per second avq learns from, against references measured in the same run.

Every figure is a ratio to a reference timed in this same process (the machine is
shared and noisy), plus the absolute number:

1. fused training on GridMaze ``lau2002`` (``avq-paper``, ``avq``, ``tabular``) against a
   minimal hand-written Numba tabular Sarsa(λ) with the maze inside the loop
   (:func:`reference_steps_per_second`, the practical speed limit for this work);
1b. training with planning on GridMaze ``lau2002`` (``avq-plan``, ``tabular-ps``, fused, their default
   backup budget): env steps per second from the start of learning (exploring, the model growing) and
   once learned, and the planner's backups per second (every state of the learned model queued and
   swept) against a hand-written compiled loop of the same backup (Bellman backups over a
   deterministic model held as dense arrays, no queue: the speed limit of a backup here);
2. the generic path (AVQ stepping a Gymnasium environment from Python) against a
   loop that only steps the same environment with pre-drawn random actions, on classic
   tasks and on ``bench/CopyMaze-v0``: ``lau2002`` under an id avq does not know (a
   subclass of GridMaze, so nothing is fused), a fast env on which the agent's own work
   per step shows (the ratio, and the agent's µs per step: 1/agent - 1/env-only);
2b. ε-greedy: the fused loops call the one compiled ``epsilon_greedy`` (inlined) where an
   earlier version wrote the draws out by hand; both timed on the same loop;
3. nearest-vector queries inside a compiled loop, 20 to 20,000 vectors, brute force
   against the k-d tree (``scipy.spatial.cKDTree``) the codebook uses for batches;
4. ``avq reproduce`` with its defaults, process start to files written, warm cache;
5. start-up: the first run with an empty compilation cache against a cached one.

    python benchmarks/speed.py            # everything (a few minutes)
    python benchmarks/speed.py --quick    # smaller budgets, skips 4 and 5
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import gymnasium as gym
import numpy as np
from numba import njit

import avq
from avq.agents._td import epsilon_greedy, greedy_ties, nth_tie
from avq.envs.grid_maze import GridMaze, grid_move
from avq.envs.layouts import load_layout
from avq.quantizer import nearest_index


class CopyMaze(GridMaze):
    """``lau2002`` as a plain copy under another id: avq does not know it, so nothing is fused."""


if "bench/CopyMaze-v0" not in gym.registry:
    gym.register("bench/CopyMaze-v0", entry_point=CopyMaze, max_episode_steps=100)


@njit(cache=True)
def _reference_run(n_steps, seed, walls, starts, gx, gy):
    """Tabular Sarsa(λ) on the maze, replacing traces over the visited set, 100-step trials."""
    np.random.seed(seed)
    h, w = walls.shape
    q = np.zeros((h * w, 4))
    e = np.zeros((h * w, 4))
    visited = np.empty(h * w * 4, np.int64)
    alpha, lam, eps = 0.1, 0.7, 0.1
    steps = 0
    while steps < n_steps:
        k = np.random.randint(starts.shape[0])
        x, y = starts[k, 0], starts[k, 1]
        s = y * w + x
        a = np.random.randint(4) if np.random.random() < eps else np.argmax(q[s])
        nv = 0
        for _t in range(100):
            x, y, r, term, _ = grid_move(walls, x, y, a, gx, gy)
            steps += 1
            s2 = y * w + x
            if term:
                delta = r - q[s, a]
                a2 = 0
            else:
                a2 = np.random.randint(4) if np.random.random() < eps else np.argmax(q[s2])
                delta = r + q[s2, a2] - q[s, a]
            if e[s, a] == 0.0:
                visited[nv] = s * 4 + a
                nv += 1
            e[s, a] = 1.0
            for i in range(nv):
                j = visited[i]
                q[j // 4, j % 4] += alpha * delta * e[j // 4, j % 4]
                e[j // 4, j % 4] *= lam
            if term:
                break
            s, a = s2, a2
        for i in range(nv):
            j = visited[i]
            e[j // 4, j % 4] = 0.0
    return steps


def reference_steps_per_second(n_steps: int) -> float:
    lay = load_layout("lau2002")
    walls = np.ascontiguousarray(lay.walls)
    starts = lay.free_positions(include_goal=False)
    _reference_run(1000, 0, walls, starts, lay.goal[0], lay.goal[1])
    best = 0.0
    for rep in range(3):
        t = time.perf_counter()
        s = _reference_run(n_steps, rep, walls, starts, lay.goal[0], lay.goal[1])
        best = max(best, s / (time.perf_counter() - t))
    return best


def avq_fused_steps_per_second(name: str, episodes: int) -> tuple[float, int]:
    """Training throughput on the fused path, after a warm-up that also grows the codebook (or table)."""
    best = 0.0
    for rep in range(3):
        agent = avq.make_agent(name, gym.make("avq/GridMaze-v0"), seed=rep)
        agent.learn(total_episodes=20)
        t = time.perf_counter()
        before = agent.num_timesteps
        agent.learn(total_episodes=episodes)
        best = max(best, (agent.num_timesteps - before) / (time.perf_counter() - t))
    return best, agent.n_cells


@njit(cache=True)
def _reference_backups(n_sweeps, nxt, rew, V):
    """Value iteration sweeps over a deterministic model: ``Q[s, a] = rew[s, a] + V[nxt[s, a]]`` (-1: terminal),
    ``V[s] = max_a Q[s, a]``. Returns the backups done (one per state)."""
    n, m = nxt.shape
    done = 0
    for _ in range(n_sweeps):
        for s in range(n):
            best = -np.inf
            for a in range(m):
                t = nxt[s, a]
                q = rew[s, a] + (V[t] if t >= 0 else 0.0)
                if q > best:
                    best = q
            V[s] = best
            done += 1
    return done


def reference_backups_per_second(n_states: int = 98, n_sweeps: int = 20_000) -> float:
    rng = np.random.default_rng(0)
    nxt = rng.integers(-1, n_states, size=(n_states, 4))
    rew = -rng.random((n_states, 4))
    V = np.zeros(n_states)
    _reference_backups(2, nxt, rew, V)
    best = 0.0
    for _ in range(3):
        t = time.perf_counter()
        done = _reference_backups(n_sweeps, nxt, rew, V)
        best = max(best, done / (time.perf_counter() - t))
    return best


def planner_backups_per_second(name: str, reps: int = 200) -> float:
    """Backups per second of the planner itself: the model of an agent trained on ``lau2002``, every state
    queued and swept (``Model.sweep``: the heap, the successor lists, the backup)."""
    agent = avq.make_agent(name, gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=500)
    model = agent.model_
    best = 0.0
    for _ in range(reps):
        for s in range(model.n_states):
            model.queue(s, 1.0 + s)
        t = time.perf_counter()
        done = model.sweep(model.n_states)
        best = max(best, done / (time.perf_counter() - t))
    return best


def planning_steps_per_second(name: str, episodes: int) -> tuple[float, float, float, int]:
    """``(steps/s while learning from scratch, steps/s once learned, backups/s while learning, cells)`` on the
    fused path, the best of 3 runs (the first episodes of the first run compile nothing: warmed up before)."""
    avq.make_agent(name, gym.make("avq/GridMaze-v0"), seed=99).learn(total_episodes=5)  # compile
    fresh = learned = rate = 0.0
    for rep in range(3):
        agent = avq.make_agent(name, gym.make("avq/GridMaze-v0"), seed=rep)
        t = time.perf_counter()
        agent.learn(total_episodes=episodes)
        dt = time.perf_counter() - t
        fresh = max(fresh, agent.num_timesteps / dt)
        rate = max(rate, agent.backups_ / dt)
        before = agent.num_timesteps
        t = time.perf_counter()
        agent.learn(total_episodes=episodes)
        learned = max(learned, (agent.num_timesteps - before) / (time.perf_counter() - t))
    return fresh, learned, rate, agent.n_cells


def env_only_steps_per_second(env_id: str, n_steps: int) -> float:
    env = gym.make(env_id)
    actions = np.random.default_rng(0).integers(env.action_space.n, size=n_steps)
    env.reset(seed=0)
    t = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return n_steps / (time.perf_counter() - t)


def generic_steps_per_second(name: str, env_id: str, n_steps: int) -> float:
    extra = {"fused": False} if name.startswith("avq") else {}  # the generic path even on a built-in maze
    agent = avq.make_agent(name, gym.make(env_id), seed=0, **extra)
    agent.learn(total_timesteps=2000)
    t = time.perf_counter()
    agent.learn(total_timesteps=n_steps)
    return n_steps / (time.perf_counter() - t)


def paired_generic(name: str, env_id: str, n_steps: int, reps: int = 5) -> tuple[float, float]:
    """Best of ``reps`` alternating runs of env-only and the agent (the machine is shared and noisy)."""
    base = agent = 0.0
    for _ in range(reps):
        base = max(base, env_only_steps_per_second(env_id, n_steps))
        agent = max(agent, generic_steps_per_second(name, env_id, n_steps))
    return agent, base


@njit(cache=True)
def _decisions_shared(rng, q, n, eps):
    s = 0
    for k in range(n):
        s += epsilon_greedy(rng, q, k % q.shape[0], eps)
    return s


@njit(cache=True)
def _decisions_by_hand(rng, q, n, eps):
    s = 0
    for k in range(n):
        row = k % q.shape[0]
        if rng.random() < eps:
            a = rng.integers(0, q.shape[1])
        else:
            a, n_ties = greedy_ties(q, row)
            if n_ties > 1:
                a = nth_tie(q, row, rng.integers(0, n_ties))
        s += a
    return s


def decisions_per_second(n: int = 2_000_000) -> tuple[float, float]:
    """ε-greedy decisions per second: the shared helper against the same draws written out by hand."""
    q = np.random.default_rng(0).integers(0, 3, size=(64, 4)).astype(np.float64)  # many ties
    out = []
    for fn in (_decisions_shared, _decisions_by_hand):
        fn(np.random.default_rng(0), q, 1000, 0.1)
        best = 0.0
        for rep in range(3):
            t = time.perf_counter()
            fn(np.random.default_rng(rep), q, n, 0.1)
            best = max(best, n / (time.perf_counter() - t))
        out.append(best)
    return out[0], out[1]


@njit(cache=True)
def _nearest_loop(vectors, size, queries, inv_scale):
    s = 0
    for k in range(queries.shape[0]):
        i, _ = nearest_index(vectors, size, queries[k], inv_scale)
        s += i
    return s


def nearest_table(sizes=(20, 100, 1000, 5000, 20000), n_queries=20000) -> list[tuple[int, float, float]]:
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(0)
    rows = []
    inv = np.ones(2)
    queries = rng.random((n_queries, 2))
    for p in sizes:
        vectors = rng.random((p, 2))
        _nearest_loop(vectors, p, queries[:10], inv)
        t = time.perf_counter()
        _nearest_loop(vectors, p, queries, inv)
        brute = (time.perf_counter() - t) / n_queries * 1e6
        tree = cKDTree(vectors)
        t = time.perf_counter()
        tree.query(queries, k=1)
        kd = (time.perf_counter() - t) / n_queries * 1e6
        rows.append((p, brute, kd))
    return rows


def timed_command(args: list[str], env: dict | None = None) -> float:
    t = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True, env=env)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    scale = 0.2 if args.quick else 1.0
    print(f"machine: {os.cpu_count()} cores; numpy {np.__version__}; avq {avq.__version__}")
    ref = reference_steps_per_second(int(5_000_000 * scale))
    print(f"\n1. fused training on GridMaze lau2002 (reference: Numba tabular Sarsa(λ), {ref / 1e6:.2f} M steps/s)")
    print(f"   {'agent':<10} {'M steps/s':>10} {'of reference':>13} {'cells':>6}")
    for name in ("avq-paper", "avq-maze", "tabular"):
        sps, cells = avq_fused_steps_per_second(name, int(10000 * scale) or 100)
        print(f"   {name:<10} {sps / 1e6:>10.2f} {sps / ref:>12.0%} {cells:>6}")

    ref_b = reference_backups_per_second()
    print(
        f"\n1b. training with planning on GridMaze lau2002, fused, default budget (reference: value iteration "
        f"sweeps by hand, {ref_b / 1e6:.1f} M backups/s)"
    )
    print(
        f"   {'agent':<16} {'M steps/s learning':>19} {'once learned':>13} {'planner M backups/s':>20} "
        f"{'of reference':>13} {'cells':>6}"
    )
    # avq on the grid maze: avq-plan's maze entry with merging (rho 25, known_radius 0.3).
    for name in ("avq-plan", "tabular-ps", "avq"):
        fresh, learned, _, cells = planning_steps_per_second(name, int(2000 * scale) or 100)
        rate = planner_backups_per_second(name)
        label = name + (" (merging)" if name == "avq" else "")
        print(
            f"   {label:<16} {fresh / 1e6:>19.2f} {learned / 1e6:>13.2f} {rate / 1e6:>20.1f} {rate / ref_b:>12.0%} "
            f"{cells:>6}  ({fresh / ref:.0%} of the fused reference while learning)"
        )

    print("\n2. generic path (Python steps the environment; reference: the same env stepped with random actions)")
    print(f"   {'env':<18} {'agent':<10} {'k steps/s':>10} {'env only':>10} {'ratio':>6} {'agent µs/step':>14}")
    n = int(100_000 * scale)
    for env_id, name in (
        ("bench/CopyMaze-v0", "avq-paper"),
        ("bench/CopyMaze-v0", "avq-sarsa"),
        ("bench/CopyMaze-v0", "tabular"),
        ("bench/CopyMaze-v0", "avq-plan"),
        ("bench/CopyMaze-v0", "tabular-ps"),
        ("MountainCar-v0", "avq"),
        ("MountainCar-v0", "avq-sarsa"),
        ("MountainCar-v0", "tiles"),
        ("MountainCar-v0", "grid"),
        ("avq/RobotMaze-v0", "avq"),
    ):
        sps, base = paired_generic(name, env_id, n, reps=3 if args.quick else 5)
        work = (1 / sps - 1 / base) * 1e6
        print(f"   {env_id:<18} {name:<10} {sps / 1e3:>10.1f} {base / 1e3:>10.1f} {sps / base:>6.0%} {work:>14.2f}")

    shared, by_hand = decisions_per_second(int(2_000_000 * scale))
    print(
        f"\n2b. ε-greedy in compiled loops: shared helper {shared / 1e6:.1f} M decisions/s, written out by hand "
        f"{by_hand / 1e6:.1f} M ({shared / by_hand:.0%})"
    )

    print("\n3. nearest vector, µs per query (2-D): brute force in a compiled loop vs k-d tree batch query")
    print(f"   {'vectors':>8} {'brute':>8} {'k-d tree':>9}")
    for p, brute, kd in nearest_table():
        print(f"   {p:>8} {brute:>8.3f} {kd:>9.3f}")

    if args.quick:
        return
    avq_bin = os.path.join(os.path.dirname(sys.executable), "avq")
    with tempfile.TemporaryDirectory() as tmp:
        timed_command([avq_bin, "reproduce", "--out", os.path.join(tmp, "warm"), "--no-progress"])
        warm = min(
            timed_command([avq_bin, "reproduce", "--out", os.path.join(tmp, f"r{k}"), "--no-progress"])
            for k in range(2)
        )
        print(f"\n4. avq reproduce (defaults), process start to files written, warm cache: {warm:.1f} s")
        cold_env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "numba-cache"))
        probe = [
            sys.executable,
            "-c",
            "import gymnasium as gym, avq; avq.make_agent('avq-paper', gym.make('avq/GridMaze-v0'), seed=0)"
            ".learn(total_episodes=5)",
        ]
        cold = timed_command(probe, cold_env)
        cached = timed_command(probe, cold_env)
        print(f"5. start-up (import, make, 5 episodes): empty compilation cache {cold:.1f} s, cached {cached:.1f} s")


if __name__ == "__main__":
    main()
